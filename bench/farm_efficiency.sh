#!/usr/bin/env bash
# Farm efficiency, measured in one run: samples/s of a render through a coordinator with
# 2 workers of 1 thread each, divided by samples/s of `aliquot render --threads 2` on the
# same render. Both rates are the coordinator's own (merged samples / render wall time).
# Usage: bench/farm_efficiency.sh [aliquot] [resolution] [spp]
set -euo pipefail
aliquot=${1:-build/bin/aliquot}
resolution=${2:-256x256}
spp=${3:-128}
tmp=$(mktemp -d)
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT

render=(--scene cornell-box --resolution "$resolution" --spp "$spp" --seed 1)
embedded=$("$aliquot" render "${render[@]}" --threads 2 --out "$tmp/embedded.exr" --json)

"$aliquot" coordinator --grpc "127.0.0.1:$port" --data "$tmp/data" 2>"$tmp/coordinator.log" &
pids+=($!)
client_token=(--token-file "$tmp/data/client.token")  # made by the coordinator at start
for _ in $(seq 100); do "$aliquot" status --coordinator "127.0.0.1:$port" "${client_token[@]}" >/dev/null 2>&1 && break; sleep 0.1; done
for w in a b; do
    "$aliquot" worker --coordinator "127.0.0.1:$port" --threads 1 --name "$w" --token-file "$tmp/data/worker.token" 2>"$tmp/worker-$w.log" &
    pids+=($!)
done
sleep 0.5  # both workers registered and polling before the clock starts
farm=$("$aliquot" submit --coordinator "127.0.0.1:$port" "${client_token[@]}" "${render[@]}" --out "$tmp/farm.exr" --json)
identical=false
cmp -s "$tmp/embedded.exr" "$tmp/farm.exr" && identical=true

python3 - "$embedded" "$farm" "$identical" <<'PY'
import json, sys
e, f = json.loads(sys.argv[1]), json.loads(sys.argv[2])
print(json.dumps({
    "render": f"cornell-box {e['width']}x{e['height']} {e['spp']} spp",
    "embedded_samples_per_second": e["samples_per_second"],
    "farm_samples_per_second": f["samples_per_second"],
    "farm_efficiency": f["samples_per_second"] / e["samples_per_second"],
    "identical_output": sys.argv[3] == "true",
}, indent=2))
PY
