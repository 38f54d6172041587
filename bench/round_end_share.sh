#!/usr/bin/env bash
# The coordinator's share of a real farm's render, issue 14 item 4 measured rather than
# extrapolated: a coordinator and WORKERS workers of one thread each render the Cornell box
# at RESOLUTION and SPP (budget = SPP x pixels) with each method in turn, and the
# coordinator's own counters (`aliquot_round_end_seconds_total`, `..._cpu_seconds_total`,
# `aliquot_rounds_ended_total` on /metrics) are read before and after each render. A round
# end holds up the render's workers unless the round after it was opened ahead (its jobs
# out before the round end: docs/FARM.md, "Two rounds out"); those that did are
# `aliquot_round_end_wait_seconds_total`, so share = round-end wait ÷ the render's seconds
# is the time the farm waited on the coordinator. On one machine the coordinator and the workers share its cores, so a round
# end's CPU is also taken from the tracing: this is the farm this machine can run, not a
# farm of many machines (bench/farm_scale.cpp extrapolates to those). Per round, the
# rounds' own seconds (from /api/renders/ID/rounds) against a round end's mean give
# largest_round_share: the round that waited on the coordinator the most.
# Each round end's own time is read by polling the counters while the render runs (every
# 20 ms; a round end is counted when the rounds counter moves), so largest_round_share is
# each round's own round end ÷ the round's seconds.
# A method written `optimal:K` (or `optimal-time:K`) runs with --steer-rounds K, and
# `optimal/P` with --plan-ahead P (both: `optimal:K/P`).
# Usage: bench/round_end_share.sh [aliquot] [resolution] [spp] [methods] [workers]
set -euo pipefail
aliquot=${1:-build/bin/aliquot}
resolution=${2:-1920x1080}
spp=${3:-64}
methods=${4:-uniform,dammertz,adaptive,optimal,optimal-time,cycles}
workers=${5:-2}
tmp=$(mktemp -d)
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
grpc=$(free_port)
http=$(free_port)
pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; wait 2>/dev/null; rm -rf "$tmp"; }
trap cleanup EXIT

"$aliquot" coordinator --grpc "127.0.0.1:$grpc" --http "127.0.0.1:$http" --data "$tmp/data" \
    2>"$tmp/coordinator.log" &
pids+=($!)
token=(--token-file "$tmp/data/client.token")  # made by the coordinator at start
for _ in $(seq 100); do "$aliquot" status --coordinator "127.0.0.1:$grpc" "${token[@]}" >/dev/null 2>&1 && break; sleep 0.1; done
for w in $(seq "$workers"); do
    "$aliquot" worker --coordinator "127.0.0.1:$grpc" --threads 1 --name "w$w" \
        --token-file "$tmp/data/worker.token" 2>"$tmp/worker-$w.log" &
    pids+=($!)
done
sleep 0.5

# The three counters, as "rounds seconds cpu_seconds"; with `poll FILE`, a line to FILE
# each time the rounds counter moves, until killed.
cat >"$tmp/scrape.py" <<'PY'
import sys, time, urllib.request
port, token_file = sys.argv[1], sys.argv[2]
token = open(token_file).read().strip()
req = urllib.request.Request(f"http://127.0.0.1:{port}/metrics",
                             headers={"Authorization": f"Bearer {token}"})
def scrape():
    values = {}
    for line in urllib.request.urlopen(req, timeout=10).read().decode().splitlines():
        if line and not line.startswith("#"):
            name, value = line.rsplit(" ", 1)
            values[name] = float(value)
    return (values["aliquot_rounds_ended_total"], values["aliquot_round_end_seconds_total"],
            values["aliquot_round_end_cpu_seconds_total"],
            values["aliquot_round_end_wait_seconds_total"])
if len(sys.argv) > 3:
    last = None
    with open(sys.argv[3], "a") as out:
        while True:
            now = scrape()
            if last is None or now[0] != last[0]:
                print(*now, flush=True, file=out)
                last = now
            time.sleep(0.02)
print(*scrape())
PY
scrape() { python3 "$tmp/scrape.py" "$http" "$tmp/data/client.token"; }

for method in ${methods//,/ }; do
    base=${method%%/*}
    args=(--method "${base%%:*}")
    [[ $base == *:* ]] && args+=(--steer-rounds "${base#*:}")
    [[ $method == */* ]] && args+=(--plan-ahead "${method#*/}")
    before=$(scrape)
    : >"$tmp/ends"
    python3 "$tmp/scrape.py" "$http" "$tmp/data/client.token" "$tmp/ends" &
    poller=$!
    result=$("$aliquot" submit --coordinator "127.0.0.1:$grpc" "${token[@]}" --scene cornell-box \
        --resolution "$resolution" --budget "$(python3 -c "w,h='$resolution'.split('x'); print(int(w)*int(h)*$spp)")" \
        --seed 1 "${args[@]}" --wait --json)
    sleep 0.1
    kill "$poller" 2>/dev/null || true
    wait "$poller" 2>/dev/null || true
    after=$(scrape)
    python3 - "$method" "$before" "$after" "$result" "$http" "$tmp/data/client.token" "$tmp/ends" <<'PY'
import json, sys, urllib.request
method, before, after, result = sys.argv[1], sys.argv[2].split(), sys.argv[3].split(), sys.argv[4]
port, token = sys.argv[5], open(sys.argv[6]).read().strip()
polled = [tuple(map(float, line.split())) for line in open(sys.argv[7]) if line.strip()]
r = json.loads(result.strip().splitlines()[-1])
rounds, wall, cpu, wait = (float(a) - float(b) for a, b in zip(after, before))
seconds = float(r["seconds"])
each = wall / max(rounds, 1)
# Each round end's wall time, from the polled counters (two ends within one poll share
# their sum evenly); the round end at the end of round k holds up round k + 1.
end_seconds, wait_seconds = [], []
for (r0, s0, _, w0), (r1, s1, _, w1) in zip(polled, polled[1:]):
    n = int(round(r1 - r0))
    end_seconds += [(s1 - s0) / n] * n if n > 0 else []
    wait_seconds += [(w1 - w0) / n] * n if n > 0 else []
# A round's seconds run from the render's time at the end of the round before to its own,
# so the round end that planned it is included.
req = urllib.request.Request(f"http://127.0.0.1:{port}/api/renders/{r['id']}/rounds",
                             headers={"Authorization": f"Bearer {token}"})
ends = [row[3] for row in json.loads(urllib.request.urlopen(req, timeout=10).read())["rows"]]
round_seconds = [b - a for a, b in zip(ends, ends[1:])]
# The first polled line is the state before the render; its round ends follow in order,
# the last one (which plans nothing) after the final round.
per_round = [e / d for e, d in zip(wait_seconds, round_seconds) if d > 0]
print(json.dumps({
    "method": method, "image": f"{r['width']}x{r['height']}", "state": r["state"],
    "samples": r["samples_done"], "rounds": int(rounds), "render_seconds": seconds,
    "round_end_seconds": round(wall, 4), "round_end_cpu_seconds": round(cpu, 4),
    "round_end_ms_each": round(1e3 * each, 1),
    "round_end_wait_seconds": round(wait, 4),
    "share": round(wait / seconds, 4) if seconds > 0 else None,
    "round_seconds": [round(d, 3) for d in round_seconds],
    "round_end_ms": [round(1e3 * e, 1) for e in end_seconds],
    "round_wait_ms": [round(1e3 * e, 1) for e in wait_seconds],
    "largest_round_share": round(max(per_round), 4) if per_round else None,
}))
PY
done
