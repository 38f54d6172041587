#!/usr/bin/env python3
"""Soak: submit, cancel and delete distinct ~1 MB scenes; the coordinator's memory.

Issue 30, item 5: every scene ever submitted stayed in the coordinator's memory (200 cycles
of distinct 1 MB scenes: 28 -> 261 MB, the database empty). A coordinator (--data in a temp
dir, no workers) gets N cycles of `aliquot submit` (the Cornell box with a mesh of random
triangles, ~1 MB of JSON, different each cycle), `aliquot cancel` and `aliquot delete`.
Prints the coordinator's VmRSS after the first cycles (the start: the store, the code and
the allocator warmed up) and at the end, and their ratio. A bench, not a test: exit status 1
when the ratio passes --max-ratio (1.2) or a cycle failed. The quick test is
coordinator_test.cpp's ScenesLeaveMemoryWithTheLastRenderThatUsesThem (200 cycles, the
scene map back to empty).

Usage: soak_submit.py path/to/aliquot [--cycles 1000] [--scene-kb 1024] [--warmup 20]
"""
import argparse
import json
import os
import random
import shutil
import socket
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))


def scene_text(base, kb, rng):
    """The Cornell box with a small mesh of random triangles, about `kb` KiB of JSON."""
    scene = json.loads(json.dumps(base))
    positions, triangles = [], []
    text_size = 0
    while text_size < kb * 1024:
        n = len(positions)
        for _ in range(3):
            positions.append([round(rng.uniform(-0.9, 0.9), 6) for _ in range(3)])
        triangles.append([n, n + 1, n + 2])
        text_size += 3 * 30 + 16  # about what a triangle's numbers print to
    scene["shapes"].append({"type": "mesh", "material": "white",
                            "positions": positions, "triangles": triangles})
    return json.dumps(scene)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("aliquot")
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--scene-kb", type=int, default=1024)
    ap.add_argument("--warmup", type=int, default=20,
                    help="cycles before the starting RSS is taken")
    ap.add_argument("--max-ratio", type=float, default=1.2)
    args = ap.parse_args()
    with open(os.path.join(HERE, "..", "scenes", "cornell-box.json")) as f:
        base = json.load(f)
    tmp = tempfile.mkdtemp(prefix="aliquot-soak-submit-")
    # A copy: a rebuild of the original during a long soak must not fail its cycles.
    aliquot = os.path.join(tmp, "aliquot")
    shutil.copy2(args.aliquot, aliquot)
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        addr = f"127.0.0.1:{s.getsockname()[1]}"
    data = os.path.join(tmp, "data")
    log = open(os.path.join(tmp, "coordinator.log"), "w")
    coordinator = subprocess.Popen(
        [aliquot, "coordinator", "--grpc", addr, "--data", data],
        stdout=log, stderr=subprocess.STDOUT)
    client = ["--coordinator", addr, "--token-file", os.path.join(data, "client.token")]

    def run(*a):
        r = subprocess.run([aliquot, *a, *client], capture_output=True, text=True,
                           timeout=120)
        if r.returncode != 0:
            raise RuntimeError(f"aliquot {' '.join(a)}: {r.stderr.strip()}")
        return r.stdout

    def rss_kb():
        with open(f"/proc/{coordinator.pid}/status") as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
        return -1

    failures = []
    try:
        deadline = time.time() + 30
        while subprocess.run([aliquot, "status", "--json", *client],
                             capture_output=True).returncode != 0:
            if time.time() > deadline or coordinator.poll() is not None:
                sys.exit("coordinator did not start")
            time.sleep(0.1)
        rng = random.Random(30)
        scene_file = os.path.join(tmp, "scene.json")
        start_rss = None
        start = time.time()
        for i in range(args.cycles):
            if i == args.warmup:
                start_rss = rss_kb()
            with open(scene_file, "w") as f:
                f.write(scene_text(base, args.scene_kb, rng))
            try:
                rid = json.loads(run("submit", "--scene", scene_file, "--resolution",
                                     "16x16", "--spp", "1", "--json"))["id"]
                run("cancel", rid)
                # Deleting waits for the render's end to be recorded; a cancel just made
                # may not be yet: try again briefly.
                for attempt in range(50):
                    try:
                        run("delete", rid)
                        break
                    except RuntimeError:
                        if attempt == 49:
                            raise
                        time.sleep(0.1)
            except Exception as e:  # counted, not raised: the soak goes on
                failures.append(f"cycle {i}: {e}")
            if (i + 1) % 100 == 0:
                print(f"  {i + 1} cycles, {time.time() - start:.0f} s, coordinator VmRSS "
                      f"{rss_kb() / 1024:.1f} MiB", flush=True)
        end_rss = rss_kb()
        alive = coordinator.poll() is None
    finally:
        if coordinator.poll() is None:
            coordinator.terminate()
            try:
                coordinator.wait(timeout=20)
            except subprocess.TimeoutExpired:
                coordinator.kill()
    start_rss = start_rss or -1
    ratio = end_rss / start_rss
    print(f"cycles           {args.cycles} of ~{args.scene_kb} KiB scenes, "
          f"{len(failures)} failed, {time.time() - start:.0f} s")
    print(f"RSS after {args.warmup:<6} {start_rss / 1024:.1f} MiB")
    print(f"RSS after {args.cycles:<6} {end_rss / 1024:.1f} MiB")
    print(f"ratio            {ratio:.2f} (at most {args.max_ratio})")
    for f in failures[:10]:
        print(f"  {f}")
    ok = alive and not failures and ratio <= args.max_ratio
    if ok:
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        print(f"coordinator {'alive' if alive else 'DIED'}; logs kept in {tmp}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
