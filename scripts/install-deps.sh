#!/usr/bin/env bash
# Installs the Debian packages Aliquot builds and tests with; idempotent, does nothing when
# everything is already there. Needs root (or sudo) only when something is missing.
#   scripts/install-deps.sh          everything scripts/test.sh needs (build, tests, fuzzers,
#                                    the dashboard, the study report)
#   scripts/install-deps.sh --demo   only what building the `aliquot` binary needs, without
#                                    recommended packages (scripts/demo.sh)
set -euo pipefail

mode=all
case "${1:-}" in
    "") ;;
    --demo) mode=demo ;;
    *)
        echo "install-deps.sh: unknown argument '$1' (usage: install-deps.sh [--demo])" >&2
        exit 2
        ;;
esac

# What the `aliquot` binary's build needs: CMake configures the whole project, so the
# test framework's headers (libgtest-dev) are here too. deploy/Dockerfile's BUILD_PACKAGES
# is the same list.
build_packages=(
    build-essential cmake ninja-build pkg-config
    libembree-dev libtbb-dev libopenexr-dev
    libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc
    libsqlite3-dev libgtest-dev nlohmann-json3-dev libcli11-dev
    libcpp-httplib-dev zlib1g-dev
    # The coordinator's /metrics (the registry and text format of prometheus-cpp), and
    # gRPC's standard health.proto, whose client the tests and probes build.
    prometheus-cpp-dev grpc-proto
)
test_packages=(
    git sqlite3 clang-format
    python3 python3-venv python3-pip
    # `aliquot study`'s report (studies/report.py): its plots and arrays, from Debian
    # rather than pip, which Debian's own python3 refuses (externally managed).
    python3-matplotlib python3-numpy
    # tests/ops: /metrics parsed as Prometheus does, gRPC health and reflection asked
    # from Python as probes and grpcurl do.
    python3-prometheus-client python3-grpcio python3-protobuf
    # tests/tls/run.sh: a throwaway CA and certificates, and HTTPS requests.
    openssl curl
    # tests/net: network namespaces, veth pairs and a bridge (ip), packet loss and partitions
    # (iptables' statistic match and DROP), Toxiproxy built with Debian's Go (below), which
    # builds kubeconform for tests/compose too.
    iproute2 iptables golang-go
    # tests/cli/render_test.sh: an --aovs EXR as a tool reads it (`oiiotool --info -v`).
    openimageio-tools
    # scripts/fuzz.sh: clang, and the compiler-rt archives that carry libFuzzer
    # (libclang_rt.fuzzer) and the sanitizers for Debian's clang 14.
    clang libclang-rt-14-dev
)
packages=("${build_packages[@]}")
install_options=(--no-install-recommends)
if [[ $mode == all ]]; then
    packages+=("${test_packages[@]}")
    install_options=()
    # The dashboard's build (web/build.sh) needs Node and npm; a machine that has its own
    # Node keeps it.
    command -v node >/dev/null 2>&1 || packages+=(nodejs npm)
fi

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    echo "installing: ${missing[*]}" >&2
    sudo_cmd=()
    [[ $(id -u) -eq 0 ]] || sudo_cmd=(sudo)
    "${sudo_cmd[@]}" apt-get update -qq
    DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq \
        ${install_options[@]+"${install_options[@]}"} "${missing[@]}"
fi

# Intel Open Image Denoise for `aliquot render --denoise`, `compare` and the study's denoised
# figures: Debian bookworm has no package of it, and the pyoidn wheel carries its library
# (libOpenImageDenoise.so.2, its CPU device and the TBB it needs). Into the repository's
# .venv, where coordinator/denoise looks for it at run time; only the library is used, so
# not pyoidn's Python dependencies. Once per version.
if [[ $mode == all ]]; then
    pyoidn_version=2.5.1.0
    venv=$(cd "$(dirname "$0")/.." && pwd)/.venv
    [[ -x $venv/bin/python ]] || python3 -m venv "$venv"
    if ! "$venv/bin/python" -c "import importlib.metadata as m, sys
sys.exit(m.version('pyoidn') != '$pyoidn_version')" >/dev/null 2>&1; then
        echo "installing pyoidn $pyoidn_version (Open Image Denoise) into .venv" >&2
        "$venv/bin/python" -m pip install --quiet --disable-pip-version-check --no-deps \
            "pyoidn==$pyoidn_version"
    fi
fi

# Toxiproxy (Shopify's TCP proxy with latency, jitter and cuts) for tests/net, built from the
# Go module proxy with Debian's Go into build/tools, once per version: v2.8.0 is the newest
# whose go.mod bookworm's Go 1.19 accepts (v2.9.0 asks for 1.22). Debian's go by its own path,
# since a Go of the machine's may come first on PATH; GOROOT unset for the same reason.
if [[ $mode == all ]]; then
    toxiproxy_version=v2.8.0
    tools=$(cd "$(dirname "$0")/.." && pwd)/build/tools
    toxiproxy=$tools/toxiproxy-$toxiproxy_version/toxiproxy-server
    if [[ ! -x $toxiproxy ]]; then
        echo "building toxiproxy-server $toxiproxy_version into build/tools" >&2
        go=go
        [[ -x /usr/bin/go ]] && go=/usr/bin/go  # golang-go's
        gobin=$(mktemp -d)
        env -u GOROOT GOPATH="$tools/go" GOCACHE="$tools/go/cache" GOBIN="$gobin" \
            GOFLAGS="-modcacherw -buildvcs=false" GOTOOLCHAIN=local \
            "$go" install "github.com/Shopify/toxiproxy/v2/cmd/server@$toxiproxy_version"
        mkdir -p "$(dirname "$toxiproxy")"
        mv "$gobin/server" "$toxiproxy"
        rmdir "$gobin"
    fi
    mkdir -p "$tools/bin"
    ln -sfn "../toxiproxy-$toxiproxy_version/toxiproxy-server" "$tools/bin/toxiproxy-server"
fi
