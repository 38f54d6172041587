#!/usr/bin/env bash
# One command from a fresh Debian machine to every test passing: installs what is missing,
# builds, runs the unit tests (ctest) and the integration tests; non-zero on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
# install-deps.sh put Open Image Denoise in .venv: the denoise tests fail, not skip, without it.
export ALIQUOT_REQUIRE_OIDN=1
bash scripts/build.sh

failures=()
run() {
    local name=$1
    shift
    echo "=== $name"
    if "$@"; then echo "=== $name: passed"; else echo "=== $name: FAILED"; failures+=("$name"); fi
}

run "format" bash scripts/format.sh --check
run "docs" python3 tests/docs/json_blocks_test.py
run "unit tests" ctest --test-dir build --output-on-failure --timeout 600
run "cli" bash tests/cli/render_test.sh build/bin/aliquot
run "farm" python3 tests/farm/farm_test.py build/bin/aliquot
# gRPC health and reflection, /metrics through Prometheus' parser, a worker's liveness file.
# Debian's own Python: its python3-grpcio and python3-prometheus-client are installed for
# it, whatever python3 comes first on PATH.
run "ops" /usr/bin/python3 tests/ops/ops_test.py build/bin/aliquot
# scripts/demo.sh names the step that failed and stops there (stand-in tools, no network).
run "demo script" bash tests/ops/demo_script_test.sh
# A CA made with openssl, the farm and the HTTP API over TLS: a few seconds.
run "tls" bash tests/tls/run.sh build/bin/aliquot
# Workers killed and stopped, the coordinator killed, while every method renders: about 1-2 min.
run "chaos" python3 tests/chaos/chaos_test.py build/bin/aliquot
# The farm across network namespaces: Toxiproxy's delay and jitter, 1 % packet loss, a
# worker partitioned past its lease; every method byte-identical to embedded: about 20-40 s.
run "network" python3 tests/net/net_test.py build/bin/aliquot
run "web unit tests" npm --prefix web test --silent
run "web end-to-end" bash tests/web/run.sh build/bin/aliquot
run "compose" bash tests/compose/run.sh build/bin/aliquot
run "study" bash tests/study/run.sh build/bin/aliquot
run "validation against Mitsuba 3" bash tests/validation/run.sh build/bin/aliquot
# libFuzzer targets, about a minute in all; builds its own build-fuzz/ with clang.
run "fuzz" bash scripts/fuzz.sh

if ((${#failures[@]})); then
    echo "failed: ${failures[*]}"
    exit 1
fi
echo "all test suites passed"
