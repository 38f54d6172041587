#!/usr/bin/env python3
"""Soak: many small renders through one farm; the coordinator's memory and every output's bytes.

A coordinator (--data in a temp dir) and two workers on loopback; N small renders (16x16, a
few spp, every method) submitted a few at a time with `aliquot submit --out`. The specs
cycle through a bounded set (methods x seeds), so each distinct spec's embedded twin
(`aliquot render`) is rendered once. Prints renders, seconds, the coordinator's VmRSS after
the first 100 and after all of them, their ratio, and how many outputs differ from their
twin. A bench, not a test: exit status 1 only on a mismatch or a failed render.

Usage: soak.py path/to/aliquot [--renders 1000] [--parallel 4] [--seeds 12]
"""
import argparse
import concurrent.futures
import filecmp
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time

METHODS = [
    ["--method", "uniform"],
    ["--method", "dammertz", "--samples-per-iteration", "4"],
    ["--method", "adaptive", "--initial-spp", "2"],
    ["--method", "optimal", "--min-spp", "2"],
    ["--method", "optimal-time", "--min-spp", "2"],
]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("aliquot")
    ap.add_argument("--renders", type=int, default=1000)
    ap.add_argument("--parallel", type=int, default=4, help="submissions in flight")
    ap.add_argument("--seeds", type=int, default=12, help="distinct seeds per method")
    args = ap.parse_args()
    aliquot = os.path.abspath(args.aliquot)
    tmp = tempfile.mkdtemp(prefix="aliquot-soak-")

    def run(*a, timeout=300):
        r = subprocess.run([aliquot, *a], capture_output=True, text=True, timeout=timeout)
        if r.returncode != 0:
            raise RuntimeError(f"aliquot {' '.join(a)}: {r.stderr.strip()}")
        return r

    specs = [["--scene", "cornell-box", "--resolution", "16x16", "--spp", "8",
              "--seed", str(1000 + s), *m] for s in range(args.seeds) for m in METHODS]
    print(f"{len(specs)} distinct specs; rendering their embedded twins", flush=True)
    twins = {}
    t = time.time()
    with concurrent.futures.ThreadPoolExecutor(2) as pool:
        def twin(i):
            path = os.path.join(tmp, f"twin-{i}.exr")
            run("render", *specs[i], "--threads", "1", "--out", path)
            return i, path
        for i, path in pool.map(twin, range(len(specs))):
            twins[i] = path
    print(f"twins rendered in {time.time() - t:.0f} s", flush=True)

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        addr = f"127.0.0.1:{s.getsockname()[1]}"
    procs = []
    logs = open(os.path.join(tmp, "farm.log"), "w")
    coordinator = subprocess.Popen(
        [aliquot, "coordinator", "--grpc", addr, "--data", os.path.join(tmp, "data")],
        stdout=logs, stderr=subprocess.STDOUT)
    procs.append(coordinator)
    deadline = time.time() + 30
    # The coordinator makes its tokens in its data directory before it listens.
    client_token = ["--token-file", os.path.join(tmp, "data", "client.token")]
    while subprocess.run([aliquot, "status", "--coordinator", addr, "--json", *client_token],
                         capture_output=True).returncode != 0:
        if time.time() > deadline or coordinator.poll() is not None:
            sys.exit("coordinator did not start")
        time.sleep(0.1)
    for i in range(2):
        procs.append(subprocess.Popen(
            [aliquot, "worker", "--coordinator", addr, "--threads", "1", "--name", f"w{i}",
             "--token-file", os.path.join(tmp, "data", "worker.token")],
            stdout=logs, stderr=subprocess.STDOUT))

    def rss_kb():
        with open(f"/proc/{coordinator.pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
        return -1

    lock = threading.Lock()
    state = {"done": 0, "rss100": None, "mismatches": [], "failures": []}

    def one(n):
        i = n % len(specs)
        out = os.path.join(tmp, f"farm-{n}.exr")
        try:
            run("submit", "--coordinator", addr, "--json", *specs[i], "--out", out,
                *client_token)
            same = filecmp.cmp(out, twins[i], shallow=False)
            os.remove(out)
        except Exception as e:  # counted, not raised: the soak goes on
            with lock:
                state["failures"].append(f"render {n}: {e}")
            return
        with lock:
            if not same:
                state["mismatches"].append(f"render {n} ({' '.join(specs[i])})")
            state["done"] += 1
            if state["done"] == 100:
                state["rss100"] = rss_kb()
            if state["done"] % 100 == 0:
                print(f"  {state['done']} renders, {time.time() - start:.0f} s, "
                      f"coordinator VmRSS {rss_kb() / 1024:.1f} MiB", flush=True)

    start = time.time()
    with concurrent.futures.ThreadPoolExecutor(args.parallel) as pool:
        list(pool.map(one, range(args.renders)))
    seconds = time.time() - start
    rss_end = rss_kb()
    alive = coordinator.poll() is None
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()

    rss100 = state["rss100"] or -1
    print(f"renders          {state['done']} of {args.renders} "
          f"({len(specs)} distinct specs, {args.parallel} in flight)")
    print(f"seconds          {seconds:.1f}")
    print(f"RSS after 100    {rss100 / 1024:.1f} MiB")
    print(f"RSS after {args.renders:<6} {rss_end / 1024:.1f} MiB")
    print(f"ratio            {rss_end / rss100:.2f}")
    print(f"mismatches       {len(state['mismatches'])}")
    print(f"failed renders   {len(state['failures'])}")
    print(f"coordinator      {'alive' if alive else 'DIED'} at the end")
    for line in (state["mismatches"] + state["failures"])[:20]:
        print("  " + line)
    bad = state["mismatches"] or state["failures"] or not alive
    if bad:
        print(f"logs kept in {tmp}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
