#!/usr/bin/env bash
# Farm efficiency, measured in one interleaved run: samples/s of a render through a
# coordinator with 2 workers of 1 thread each, divided by samples/s of
# `aliquot render --threads 2` on the same render. Both rates are the coordinator's own
# (merged samples / render wall time). A one-second render moves ±10 % from run to run on
# a shared machine, so the two alternate (which goes first alternates too) REPEATS times,
# and the ratio of the median rates is the headline; every pair's ratio is printed too.
# The CPU each side spent a render is printed beside them (the embedded process; the
# coordinator and both workers across a submission), since on a shared machine the rates
# move more from minute to minute than the farm's own cost does. Both include writing
# the EXR (the farm twice: its render directory and `--out`); the embedded process also
# builds the scene's BVH each time, which the workers keep between renders.
# Usage: bench/farm_efficiency.sh [aliquot] [resolution] [spp] [repeats]
set -euo pipefail
aliquot=${1:-build/bin/aliquot}
resolution=${2:-256x256}
spp=${3:-128}
repeats=${4:-5}
tmp=$(mktemp -d)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT

render=(--scene cornell-box --resolution "$resolution" --spp "$spp" --seed 1)
"$aliquot" coordinator --grpc "127.0.0.1:$port" --data "$tmp/data" 2>"$tmp/coordinator.log" &
pids+=($!)
client_token=(--token-file "$tmp/data/client.token")  # made by the coordinator at start
for _ in $(seq 100); do "$aliquot" status --coordinator "127.0.0.1:$port" "${client_token[@]}" >/dev/null 2>&1 && break; sleep 0.1; done
for w in a b; do
    "$aliquot" worker --coordinator "127.0.0.1:$port" --threads 1 --name "$w" --token-file "$tmp/data/worker.token" 2>"$tmp/worker-$w.log" &
    pids+=($!)
done
sleep 0.5  # both workers registered and polling before the clock starts

cpu_of() {  # user + system seconds of the given processes so far
    local total=0 p
    for p in "$@"; do total=$(awk -v t="$total" '{print t + ($14 + $15) / 100}' "/proc/$p/stat"); done
    echo "$total"
}
embedded() {
    local TIMEFORMAT='%U %S'
    { time "$aliquot" render "${render[@]}" --threads 2 --out "$tmp/embedded.exr" --json >>"$tmp/embedded.jsonl"; } 2>&1 |
        awk '{print $1 + $2}' >>"$tmp/embedded.cpu"
}
farm() {
    local before
    before=$(cpu_of "${pids[@]}")
    "$aliquot" submit --coordinator "127.0.0.1:$port" "${client_token[@]}" "${render[@]}" \
        --out "$tmp/farm.exr" --json >>"$tmp/farm.jsonl"
    awk -v a="$before" -v b="$(cpu_of "${pids[@]}")" 'BEGIN {print b - a}' >>"$tmp/farm.cpu"
    cmp -s "$tmp/embedded.exr" "$tmp/farm.exr" && echo true >>"$tmp/identical" || echo false >>"$tmp/identical"
}
embedded  # the reference image the first farm render is compared with
: >"$tmp/embedded.jsonl"
: >"$tmp/embedded.cpu"
for i in $(seq "$repeats"); do
    if ((i % 2)); then embedded; farm; else farm; embedded; fi
done

python3 - "$tmp" <<'PY'
import json, statistics, sys
tmp = sys.argv[1]
e = [json.loads(l) for l in open(f"{tmp}/embedded.jsonl")]
ecpu = [float(l) for l in open(f"{tmp}/embedded.cpu")]
fcpu = [float(l) for l in open(f"{tmp}/farm.cpu")]
f = [json.loads(l) for l in open(f"{tmp}/farm.jsonl")]
identical = [l.strip() == "true" for l in open(f"{tmp}/identical")]
es = [r["samples_per_second"] for r in e]
fs = [r["samples_per_second"] for r in f]
print(json.dumps({
    "render": f"cornell-box {e[0]['width']}x{e[0]['height']} {e[0]['spp']} spp",
    "embedded_samples_per_second": es,
    "farm_samples_per_second": fs,
    "pair_efficiency": [round(b / a, 3) for a, b in zip(es, fs)],
    "farm_efficiency": statistics.median(fs) / statistics.median(es),
    "embedded_cpu_seconds": ecpu,
    "farm_cpu_seconds": fcpu,
    "cpu_ratio": statistics.median(ecpu) / statistics.median(fcpu),
    "identical_output": all(identical),
}, indent=2))
PY
