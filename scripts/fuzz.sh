#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/) with clang into build-fuzz/ and runs each for
# SECONDS (default 12: a minute and a half for all seven), starting from its committed
# corpus in fuzz/corpus/<target>. Non-zero if any target finds a crash, a hang, a leak or an
# allocation past the limits below; the input that did it is in build-fuzz/artifacts/.
# Usage: scripts/fuzz.sh [seconds-per-target] [target ...]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-12}
shift || true
targets=("$@")
((${#targets[@]})) || targets=(scene_fuzz obj_fuzz study_fuzz render_request_fuzz job_result_fuzz
    checkpoint_fuzz exr_fuzz)

bash scripts/install-deps.sh
CC=clang CXX=clang++ cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DALIQUOT_FUZZ=ON >/dev/null
# Only the fuzzers and the rooms they link, not the whole project.
cmake --build build-fuzz --target aliquot_fuzzers --parallel "$(nproc)"

declare -A dictionary=([scene_fuzz]=json.dict [study_fuzz]=json.dict
    [render_request_fuzz]=json.dict [obj_fuzz]=obj.dict)
failures=()
for target in "${targets[@]}"; do
    seeds=fuzz/corpus/${target%_fuzz}
    # New inputs go to a working corpus in the build tree; the committed seeds stay as they are.
    work=build-fuzz/corpus/$target
    artifacts=build-fuzz/artifacts/$target/
    mkdir -p "$work" "$artifacts"
    args=(-max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=1024
          -print_final_stats=1 -artifact_prefix="$artifacts")
    [[ -n ${dictionary[$target]:-} ]] && args+=(-dict="fuzz/${dictionary[$target]}")
    echo "=== $target: ${seconds}s"
    log=build-fuzz/$target.log
    if ASAN_OPTIONS=detect_leaks=1 build-fuzz/bin/"$target" "${args[@]}" "$work" "$seeds" \
        >"$log" 2>&1; then
        grep -E '^stat::number_of_executed_units|^#[0-9]+.*DONE' "$log" || true
    else
        echo "=== $target FAILED (log: $log)"
        grep -E 'ERROR|runtime error|SUMMARY|Test unit written' "$log" | head -20 || true
        failures+=("$target")
    fi
done
if ((${#failures[@]})); then
    echo "fuzz: failed: ${failures[*]}"
    exit 1
fi
echo "fuzz: all ${#targets[@]} targets ran ${seconds}s each without a finding"
