#!/usr/bin/env python3
"""What delay, jitter and loss cost the farm: samples/s across namespaces against loopback.

For each condition a fresh farm (tests/net/net_farm.py) renders the same specs one after
another; samples/s is a render's samples over its time from start to finish as the
coordinator records it (started_at, finished_at in SQLite), and efficiency is that over
the loopback farm's (workers in the coordinator's namespace, calling its port directly).
Conditions run in turn, REPEATS times, so a change of the machine's load spreads over all
of them; the load average is printed with every row. A benchmark, not a test: it asserts
nothing. docs/FARM.md ("Across a network") has its numbers.

Usage: net_bench.py path/to/aliquot [--workers 2] [--repeats 2]   (root; standard library)
"""
import argparse
import os
import shutil
import sqlite3
import statistics
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import network  # noqa: E402
from net_farm import NetFarm  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
TOXIPROXY = os.path.join(ROOT, "build", "tools", "bin", "toxiproxy-server")
SPECS = {
    "uniform": ["--method", "uniform"],
    "optimal": ["--method", "optimal"],
    "dammertz": ["--method", "dammertz", "--samples-per-iteration", "64"],
}
# name, through, one-way delay ms, jitter ms, loss on every worker
CONDITIONS = [
    ("loopback", "loopback", 0, 0, 0.0),
    ("proxy, no delay", "proxy", 0, 0, 0.0),
    ("2 ms RTT", "proxy", 1, 1, 0.0),  # Toxiproxy takes whole milliseconds
    ("20 ms RTT", "proxy", 10, 5, 0.0),
    ("50 ms RTT", "proxy", 25, 10, 0.0),
    ("1 % loss", "proxy", 0, 0, 0.01),
    ("20 ms RTT, 1 % loss", "proxy", 10, 5, 0.01),
]


def run_condition(aliquot, workers, condition, scene, methods, tmp):
    name, through, one_way, jitter, loss = condition
    hosts = [f"w{i}" for i in range(workers)]
    net = network.Network(["coordinator", *hosts])
    farm = NetFarm(net, aliquot, TOXIPROXY, tmp, lease_seconds=30, lost_seconds=60,
                   through=through)
    rates = {}
    try:
        net.up()
        farm.start(one_way, jitter)
        for h in hosts:
            if loss:
                net.lose(h, loss)
            farm.start_worker(h)
        while len(farm.workers_now()) < workers:
            time.sleep(0.1)
        for method in methods:
            rid = farm.submit(*scene, *SPECS[method])
            finished = None
            while finished is None:  # the end record is written after the state changes
                farm.check_alive()
                time.sleep(0.1)
                db = sqlite3.connect(f"file:{farm.data}/aliquot.db?mode=ro", uri=True)
                started, finished, samples = db.execute(
                    "SELECT started_at, finished_at, samples_done FROM renders WHERE id = ?",
                    (rid,)).fetchone()
                db.close()
            rates[method] = samples / ((finished - started) / 1000.0)
    finally:
        farm.stop()
        net.down()
    return rates


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("aliquot")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--resolution", default="128x128")
    ap.add_argument("--spp", default="512")
    ap.add_argument("--methods", default=",".join(SPECS), help="comma-separated")
    ap.add_argument("--conditions", default=",".join(str(i) for i in range(len(CONDITIONS))),
                    help="comma-separated indices into CONDITIONS; 0, loopback, is needed")
    args = ap.parse_args()
    scene = ["--scene", "cornell-box", "--resolution", args.resolution, "--spp", args.spp,
             "--seed", "3"]
    methods = args.methods.split(",")
    conditions = [CONDITIONS[int(i)] for i in args.conditions.split(",")]
    if os.geteuid() != 0 or not os.access(TOXIPROXY, os.X_OK):
        print("needs root and build/tools/bin/toxiproxy-server (scripts/install-deps.sh)")
        return 1
    aliquot = os.path.abspath(args.aliquot)
    network.clean_stale()
    print(f"{args.workers} workers x 1 thread, {' '.join(scene)}; {os.cpu_count()} cores")
    results = {c[0]: {m: [] for m in methods} for c in conditions}
    for r in range(args.repeats):
        for condition in conditions:
            tmp = tempfile.mkdtemp(prefix="aliquot-netbench-")
            try:
                rates = run_condition(aliquot, args.workers, condition, scene, methods, tmp)
            finally:
                shutil.rmtree(tmp, ignore_errors=True)
            for m, v in rates.items():
                results[condition[0]][m].append(v)
            load = os.getloadavg()[0]
            print(f"  run {r + 1} {condition[0]:>20}: " +
                  "  ".join(f"{m} {v / 1e6:.2f} M/s" for m, v in rates.items()) +
                  f"  (load {load:.1f})", flush=True)
    base = {m: statistics.median(results["loopback"][m]) for m in methods}
    print(f"\n| condition | " + " | ".join(f"{m} M samples/s (efficiency)" for m in methods) +
          " |")
    print("|---|" + "---|" * len(methods))
    for c in conditions:
        cells = []
        for m in methods:
            v = statistics.median(results[c[0]][m])
            cells.append(f"{v / 1e6:.2f} ({v / base[m]:.2f})")
        print(f"| {c[0]} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
