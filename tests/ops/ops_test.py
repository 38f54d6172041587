#!/usr/bin/python3
"""What an operator's tools see of a farm of real processes on loopback: gRPC health as
Kubernetes' probes ask it, the services listed through reflection as grpcurl lists them,
/metrics parsed as Prometheus parses it, moving while a render runs, and a worker's
liveness file stopping when the worker is stuck.

Usage: ops_test.py [path/to/aliquot]
Needs Debian's python3-grpcio, python3-protobuf, python3-prometheus-client, grpc-proto and
protobuf-compiler (scripts/install-deps.sh). The farm's helpers are tests/farm/farm_test.py's.
"""
import os
import signal
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "farm"))
sys.path.insert(0, HERE)

import grpc  # noqa: E402
from prometheus_client.parser import text_string_to_metric_families  # noqa: E402

import farm_test  # noqa: E402
import grpc_probe  # noqa: E402
from farm_test import Farm, client_token, run  # noqa: E402

SERVICES = ["aliquot.v1.ClientService", "aliquot.v1.WorkerService"]
# Long enough (a few seconds on 2 cores) to be scraped in the middle.
RENDER = ["--scene", "cornell-box", "--resolution", "96x96", "--spp", "512", "--seed", "3"]


def scrape(farm, token=None):
    """/metrics as {(name, labels): value}, parsed by Prometheus' own Python parser."""
    req = urllib.request.Request(f"http://127.0.0.1:{farm.http_port}/metrics")
    if token is not None:
        req.add_header("Authorization", f"Bearer {token}")
    with urllib.request.urlopen(req, timeout=10) as r:
        assert r.headers["Content-Type"].startswith("text/plain; version=0.0.4"), r.headers
        text = r.read().decode()
    values = {}
    for family in text_string_to_metric_families(text):
        for s in family.samples:
            values[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return values


def value(metrics, name, **labels):
    return metrics[(name, tuple(sorted(labels.items())))]


def test_health_answers_per_service_without_a_token():
    farm = Farm("health")
    try:
        farm.start_coordinator()
        for service in ["", *SERVICES]:
            status = grpc_probe.health(farm.addr, service)
            assert status == "SERVING", f"{service!r}: {status}"
        try:
            grpc_probe.health(farm.addr, "aliquot.v1.NoSuchService")
            raise AssertionError("an unknown service was answered")
        except grpc.RpcError as e:
            assert e.code() == grpc.StatusCode.NOT_FOUND, e
        # As a probe runs it: the exit code says it.
        assert grpc_probe.main(["health", farm.addr]) == 0
        # `aliquot health`, the image's healthcheck, asks the same without a token.
        for service in ["", *SERVICES]:
            r = subprocess.run([farm_test.ALIQUOT, "health", "--coordinator", farm.addr,
                                *(["--service", service] if service else [])],
                               capture_output=True, text=True, timeout=60)
            assert r.returncode == 0 and r.stdout.strip() == "SERVING", (service, r)
        r = subprocess.run([farm_test.ALIQUOT, "health", "--coordinator", farm.addr,
                            "--service", "aliquot.v1.NoSuchService"],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 1 and "NoSuchService" in r.stderr, r
    finally:
        farm.stop()
    r = subprocess.run([farm_test.ALIQUOT, "health", "--coordinator", farm.addr,
                        "--timeout", "2"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stderr.startswith("aliquot: health of"), r


def test_reflection_lists_the_services_when_turned_on():
    farm = Farm("reflection")
    try:
        farm.start_coordinator("--grpc-reflection")
        listed = set(grpc_probe.list_services(farm.addr))
        want = {*SERVICES, "grpc.health.v1.Health", "grpc.reflection.v1alpha.ServerReflection"}
        assert want <= listed, listed
    finally:
        farm.stop()
    farm = Farm("no-reflection")
    try:
        farm.start_coordinator()
        try:
            grpc_probe.list_services(farm.addr)
            raise AssertionError("reflection answered without --grpc-reflection")
        except grpc.RpcError as e:
            assert e.code() == grpc.StatusCode.UNIMPLEMENTED, e
    finally:
        farm.stop()


def test_metrics_need_the_token_and_move_as_a_render_runs():
    farm = Farm("metrics", http=True)
    try:
        farm.start_coordinator()
        for token in (None, "not-the-token"):
            try:
                scrape(farm, token)
                raise AssertionError("/metrics answered without the client token")
            except urllib.error.HTTPError as e:
                assert e.code == 401, e
        token = client_token()
        idle = scrape(farm, token)
        assert value(idle, "aliquot_samples_merged_total") == 0, idle
        assert value(idle, "aliquot_renders", state="running") == 0, idle

        farm.start_worker("w", threads=2)
        render_id = farm.submit(*RENDER)["id"]
        farm.wait_until(render_id, lambda s: s["samples_done"] > 0)
        during = scrape(farm, token)
        done = farm.wait_until(render_id, lambda s: s["state"] == "done", timeout=300)
        after = scrape(farm, token)

        total = 96 * 96 * 512
        assert done["samples_done"] == total, done
        assert 0 < value(during, "aliquot_samples_merged_total") < total, during
        assert value(during, "aliquot_renders", state="running") == 1, during
        assert value(during, "aliquot_render_memory_bytes") > 0, during
        assert value(after, "aliquot_samples_merged_total") == total, after
        assert value(after, "aliquot_renders", state="running") == 0, after
        assert value(after, "aliquot_renders", state="done") == 1, after
        assert value(after, "aliquot_leases_outstanding") == 0, after
        assert value(after, "aliquot_workers", state="lost") == 0, after
        assert value(after, "aliquot_workers", state="idle") + \
            value(after, "aliquot_workers", state="busy") == 1, after
        assert value(after, "aliquot_store_write_failures_total") == 0, after
        merges = value(after, "aliquot_merge_seconds_count")
        assert merges > value(during, "aliquot_merge_seconds_count"), (during, after)
        granted = value(after, "aliquot_lease_seconds_count", outcome="granted")
        assert granted >= merges, after  # every merged job was leased first
        assert value(after, "aliquot_lease_seconds_bucket", outcome="granted",
                     le="+Inf") == granted, after
    finally:
        farm.stop()


def test_a_worker_health_file_stops_while_the_worker_is_stuck():
    farm = Farm("liveness")
    health = os.path.join(farm.dir, "worker.health")
    try:
        farm.start_coordinator()
        farm.workers["w"] = farm_test.spawn(
            "worker", "--coordinator", farm.addr, "--threads", "2", "--name", "w",
            "--health-file", health, log=os.path.join(farm.dir, "worker-w.log"))

        def wait_for_change(since):
            deadline = time.time() + 30
            while time.time() < deadline:
                if os.path.exists(health) and os.stat(health).st_mtime_ns != since:
                    return os.stat(health).st_mtime_ns
                time.sleep(0.1)
            raise AssertionError(f"{health} did not move")

        first = wait_for_change(None)
        wait_for_change(first)  # alive: it moves
        # Every thread stopped at once: the file stops where the worker stopped.
        farm.workers["w"].send_signal(signal.SIGSTOP)
        time.sleep(0.3)
        stopped = os.stat(health).st_mtime_ns
        time.sleep(3)
        assert os.stat(health).st_mtime_ns == stopped, "a stopped worker's file moved"
        farm.workers["w"].send_signal(signal.SIGCONT)
        wait_for_change(stopped)
        farm.workers["w"].terminate()
        assert farm.workers["w"].wait(timeout=30) == 0
        assert not os.path.exists(health), "a worker that ended left its health file"
        # A file it cannot make is refused at start, with the reason.
        r = run("worker", "--coordinator", farm.addr, "--health-file",
                os.path.join(farm.dir, "no-such-dir", "h"), check=False, timeout=60)
        assert r.returncode != 0 and "--health-file" in r.stderr, r.stderr
    finally:
        farm.stop()


def start_limited_coordinator(farm, nofile):
    """The coordinator under `prlimit --nofile=SOFT[:HARD]`; returns its log's path."""
    log = os.path.join(farm.dir, "coordinator.log")
    args = farm_test.with_token(["coordinator", "--grpc", farm.addr,
                                 "--data", os.path.join(farm.dir, "data")])
    farm.coordinator = subprocess.Popen(["prlimit", f"--nofile={nofile}",
                                         farm_test.ALIQUOT, *args],
                                        stdout=open(log, "w"), stderr=subprocess.STDOUT)
    farm_test.PROCS.append(farm.coordinator)
    deadline = time.time() + 20
    while time.time() < deadline:
        try:
            if grpc_probe.health(farm.addr, "", timeout=1) == "SERVING":
                return log
        except grpc.RpcError:
            time.sleep(0.1)
    raise AssertionError("coordinator did not start")


def flood(farm, connections):
    """Plain connect()s, no byte sent, all held at once, then closed."""
    held = []
    try:
        for _ in range(connections):
            s = socket.socket()
            s.settimeout(5)
            s.connect(("127.0.0.1", farm.port))
            held.append(s)
        time.sleep(1)  # the coordinator accepts them meanwhile
    finally:
        for s in held:
            s.close()


def answered_within(farm, seconds):
    deadline = time.time() + seconds
    while time.time() < deadline:
        try:
            return grpc_probe.health(farm.addr, "", timeout=2) == "SERVING"
        except grpc.RpcError:
            time.sleep(0.5)
    return False


def test_a_connection_flood_past_a_low_soft_file_limit_is_absorbed():
    # A soft limit below the hard one is raised at start: 1,000 connections fit.
    farm = Farm("flood-soft")
    try:
        log = start_limited_coordinator(farm, "256:4096")
        flood(farm, 1000)
        assert answered_within(farm, 10), "a new connection is not answered"
        assert farm.coordinator.poll() is None
        with open(log) as f:
            text = f.read()
        assert "Failed accept4" not in text, text
    finally:
        farm.stop()


def test_a_connection_flood_past_the_hard_file_limit_is_recovered_from():
    # Issue 30: gRPC 1.51 stops accepting for good after one accept fails with EMFILE;
    # the watchdog notices the deaf port and listens again (or the process exits non-zero
    # for its supervisor to restart it). Either way nobody is locked out while it runs.
    farm = Farm("flood-hard")
    try:
        log = start_limited_coordinator(farm, "256")
        flood(farm, 1000)
        answered = answered_within(farm, 60)
        with open(log) as f:
            text = f.read()
        assert "Failed accept4" in text, "the flood did not exhaust descriptors: " + text
        if farm.coordinator.poll() is None:
            assert answered, "up but deaf: " + text
            assert "listening again" in text, text
        else:
            assert farm.coordinator.returncode != 0, text
    finally:
        farm.stop()


if __name__ == "__main__":
    sys.exit(farm_test.main(globals()))
