#!/usr/bin/env python3
"""The farm across real network hops: namespaces, a bridge, delay, loss and a partition.

The coordinator and four workers are hosts of their own (network namespaces joined by veth
pairs to a bridge, tests/net/network.py). Every worker reaches the coordinator through
Toxiproxy, which holds each direction back by 10 ms ± 5 ms (a 20 ms round trip with
jitter); w1 also loses 1 % of its packets each way (iptables' statistic match in its
namespace), and w2 is cut off (every packet dropped) once it holds a lease, until the
coordinator has taken it for lost, so for longer than its lease, then healed. Meanwhile one
render of every method runs; each fetched EXR must be byte-identical to `aliquot render`
of the same spec, the partitioned worker must be heard from again after the heal, and no
process may end on its own.

Needs root (namespaces, iptables); skipped with a line saying so otherwise. Toxiproxy comes
from scripts/install-deps.sh (build/tools/bin/toxiproxy-server). Namespaces, their iptables
rules and every process are removed on every way out: an exception, SIGINT, SIGTERM, SIGHUP;
a run killed with SIGKILL is cleaned up by the next.

Usage: net_test.py path/to/aliquot [--keep]   (standard library only)
"""
import argparse
import filecmp
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import network  # noqa: E402
from net_farm import NetFarm  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
TOXIPROXY = os.path.join(ROOT, "build", "tools", "bin", "toxiproxy-server")
LEASE_SECONDS = 2.0
LOST_SECONDS = 3.0
ONE_WAY_MS, JITTER_MS = 10, 5
LOSS = 0.01
WORKERS = ["w0", "w1", "w2", "w3"]
LOSSY, PARTITIONED = "w1", "w2"
# Every method, with rounds enough that the partition lands mid-render; a few seconds of
# the farm each on two cores. Dammertz's rounds are small and many (131 here), each costing
# round trips: a smaller budget and larger iterations keep it to seconds at 20 ms.
SPEC = ["--scene", "cornell-box", "--resolution", "64x64"]
METHODS = [
    ["--spp", "1024", "--method", "uniform"],
    ["--spp", "512", "--method", "dammertz", "--samples-per-iteration", "64"],
    ["--spp", "1024", "--method", "adaptive", "--initial-spp", "16"],
    ["--spp", "1024", "--method", "optimal"],
    ["--spp", "1024", "--method", "optimal-time"],
]

T0 = time.time()


def log(msg):
    print(f"[{time.time() - T0:5.1f}s] {msg}", flush=True)


def on_signal(signum, _frame):
    # Turned into an exception so that the `finally` below tears everything down.
    raise SystemExit(128 + signum)


class Twins:
    """The embedded renders, one at a time on a thread of the test, while the farm works."""

    def __init__(self, aliquot, tmp, specs):
        self.paths, self.errors = {}, {}
        self.process, self.stopped = None, False
        self.thread = threading.Thread(target=self._main, args=(aliquot, tmp, specs),
                                       daemon=True)
        self.thread.start()

    def _main(self, aliquot, tmp, specs):
        for i, spec in enumerate(specs):
            path = os.path.join(tmp, f"twin-{i}.exr")
            if self.stopped:
                return
            self.process = subprocess.Popen(
                [aliquot, "render", *spec, "--threads", "1", "--out", path],
                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
            _, err = self.process.communicate()
            if self.process.returncode == 0:
                self.paths[i] = path
            else:
                self.errors[i] = err.strip()

    def stop(self):
        """Kills the render running, if any: it would outlive the test."""
        self.stopped = True
        if self.process is not None and self.process.poll() is None:
            self.process.kill()
        self.thread.join()

    def get(self, i):
        self.thread.join()
        if i in self.errors:
            raise AssertionError(f"embedded render {i} failed: {self.errors[i]}")
        return self.paths[i]


def wait_for(what, predicate, farm, timeout):
    """Polls predicate() until true; the farm's processes must stay up meanwhile. The
    timeout only bounds a hang: nothing here depends on how fast the farm is."""
    deadline = time.time() + timeout
    while True:
        farm.check_alive()
        value = predicate()
        if value:
            return value
        if time.time() > deadline:
            raise AssertionError(f"{what}: not within {timeout} s")
        time.sleep(0.1)


def partition_and_heal(net, farm):
    """Cuts the worker off while it holds a lease, until the coordinator has taken it for
    lost (its leases expired and handed to others), for at least twice its lease; heals."""
    held = wait_for(f"{PARTITIONED} holds a lease",
                    lambda: farm.workers_now().get(PARTITIONED, {}).get("leases"), farm, 60)
    net.partition(PARTITIONED)
    cut = time.time()
    log(f"{PARTITIONED} partitioned while holding {held}")
    wait_for(f"{PARTITIONED} lost to the coordinator",
             lambda: farm.workers_now()[PARTITIONED]["state"] == "lost" and
             not farm.workers_now()[PARTITIONED]["leases"], farm, 60)
    while time.time() - cut < 2 * LEASE_SECONDS:
        time.sleep(0.1)
    dropped = net.dropped(PARTITIONED)
    net.heal(PARTITIONED)
    seconds = time.time() - cut
    log(f"{PARTITIONED} healed after {seconds:.1f} s (lease {LEASE_SECONDS:g} s), "
        f"dropped {dropped}")
    before = farm.workers_now()[PARTITIONED]["last_seen_ms"]
    wait_for(f"{PARTITIONED} heard from after the heal",
             lambda: farm.workers_now()[PARTITIONED]["state"] != "lost" and
             farm.workers_now()[PARTITIONED]["last_seen_ms"] != before, farm, 90)
    log(f"{PARTITIONED} is back: {farm.workers_now()[PARTITIONED]['state']}")
    return seconds, dropped


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("aliquot")
    ap.add_argument("--keep", action="store_true", help="keep the temp dir even on success")
    args = ap.parse_args()
    if os.geteuid() != 0:
        print("skip network: needs root for network namespaces and iptables "
              "(CI runs as root)")
        return 0
    if not os.access(TOXIPROXY, os.X_OK):
        print(f"FAIL network: no {TOXIPROXY}; scripts/install-deps.sh builds it")
        return 1
    aliquot = os.path.abspath(args.aliquot)
    for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
        signal.signal(signum, on_signal)
    network.clean_stale()
    tmp = tempfile.mkdtemp(prefix="aliquot-net-")
    net = network.Network(["coordinator", *WORKERS])
    farm = NetFarm(net, aliquot, TOXIPROXY, tmp, LEASE_SECONDS, LOST_SECONDS)
    specs = [[*SPEC, "--seed", str(40 + i), *m] for i, m in enumerate(METHODS)]
    failures, twins = [], None
    try:
        net.up()
        farm.start(ONE_WAY_MS, JITTER_MS)
        net.lose(LOSSY, LOSS)
        for w in WORKERS:
            farm.start_worker(w)
        log(f"coordinator at {net.address('coordinator')} behind Toxiproxy "
            f"({ONE_WAY_MS}±{JITTER_MS} ms each way), workers {', '.join(WORKERS)}; "
            f"{LOSSY} loses {LOSS:.0%} of its packets; temp dir {tmp}")
        twins = Twins(aliquot, tmp, specs)
        renders = [farm.submit(*spec) for spec in specs]
        log(f"submitted {', '.join(renders)}")
        partitioned_for, partition_dropped = partition_and_heal(net, farm)
        wait_for("every render done",
                 lambda: all(farm.status(r)["state"] in ("done", "failed", "cancelled")
                             for r in renders), farm, 150)
        for i, (rid, spec) in enumerate(zip(renders, specs)):
            status = farm.status(rid)
            if status["state"] != "done":
                failures.append(f"{rid}: {status['state']} {status.get('error', '')}")
                continue
            out = os.path.join(tmp, f"farm-{rid}.exr")
            farm.client("fetch", rid, "--out", out)
            # The summary's lines, as tests/chaos prints them.
            if filecmp.cmp(out, twins.get(i), shallow=False):
                print(f"  {rid} ok: {status['rounds']} rounds, {status['samples_done']} "
                      f"samples ({spec[1]} {' '.join(spec[6:])})", flush=True)
            else:
                failures.append(f"{rid}: farm EXR differs from embedded ({' '.join(spec)})")
        workers = farm.workers_now()
        print(f"faults: {ONE_WAY_MS}±{JITTER_MS} ms each way, {LOSSY} lost {LOSS:.0%} of "
              f"its packets ({net.dropped(LOSSY)} dropped), {PARTITIONED} partitioned for "
              f"{partitioned_for:.1f} s ({partition_dropped} dropped); samples traced: " +
              ", ".join(f"{w} {workers[w]['samples_traced']}" for w in WORKERS), flush=True)
        farm.check_alive()
    except (Exception, SystemExit) as e:
        failures.append(f"{type(e).__name__}: {e}")
    finally:
        for signum in (signal.SIGTERM, signal.SIGINT, signal.SIGHUP):
            signal.signal(signum, signal.SIG_IGN)  # a second signal must not cut teardown
        if twins:
            twins.stop()
        farm.stop()
        net.down()
    elapsed = time.time() - T0
    if failures:
        print(f"FAIL network ({elapsed:.0f} s):")
        for f in failures:
            print("  " + f)
        print(f"logs kept in {tmp}")
        return 1
    print(f"ok   network ({elapsed:.0f} s, {len(renders)} renders)")
    if args.keep:
        print(f"kept {tmp}")
    else:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
