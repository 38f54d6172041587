#!/usr/bin/env python3
"""The farm with real processes on loopback: a coordinator, workers, and the CLI clients.

Every render is compared byte for byte with the same render made by `aliquot render`
embedded: determinism is what makes worker deaths and coordinator restarts testable.
Usage: farm_test.py [path/to/aliquot]   (standard library only)
"""
import concurrent.futures
import filecmp
import json
import os
import re
import shutil
import signal
import socket
import sqlite3
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

ALIQUOT = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else "build/bin/aliquot")
TMP = tempfile.mkdtemp(prefix="aliquot-farm-")
PROCS = []


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# The farm runs authenticated, as in production: the coordinators get these two tokens,
# clients the first and workers the second (issue 13). One test below lets a coordinator
# make its own in its data directory.
def write_token(name):
    path = os.path.join(TMP, name)
    with open(os.open(path, os.O_WRONLY | os.O_CREAT, 0o600), "w") as f:
        f.write(os.urandom(32).hex() + "\n")
    return path


CLIENT_TOKEN = write_token("client.token")
WORKER_TOKEN = write_token("worker.token")
CLIENT_COMMANDS = {"submit", "status", "watch", "fetch", "cancel", "priority", "delete",
                   "workers"}


def with_token(args):
    """The token for the command's role, unless the test passes its own."""
    if "--token-file" in args:
        return list(args)
    if args[0] == "worker":
        return [*args, "--token-file", WORKER_TOKEN]
    if args[0] == "coordinator":
        return [*args, "--client-token-file", CLIENT_TOKEN, "--worker-token-file", WORKER_TOKEN]
    if args[0] in CLIENT_COMMANDS:
        return [*args, "--token-file", CLIENT_TOKEN]
    return list(args)


def client_token():
    with open(CLIENT_TOKEN) as f:
        return f.read().strip()


def spawn(*args, log, cwd=None, token=True):
    p = subprocess.Popen([ALIQUOT, *(with_token(args) if token else args)],
                         stdout=open(log, "w"), stderr=subprocess.STDOUT, cwd=cwd)
    PROCS.append(p)
    return p


def run(*args, check=True, timeout=300):
    r = subprocess.run([ALIQUOT, *with_token(args)], capture_output=True, text=True,
                       timeout=timeout)
    if check and r.returncode != 0:
        raise AssertionError(f"aliquot {' '.join(args)} failed: {r.stderr.strip()}")
    return r


class Farm:
    def __init__(self, name, lease_seconds=2, lost_seconds=3, http=False):
        self.dir = os.path.join(TMP, name)
        os.makedirs(self.dir, exist_ok=True)
        self.port = free_port()
        self.addr = f"127.0.0.1:{self.port}"
        self.http_port = free_port() if http else None
        self.lease_seconds, self.lost_seconds = lease_seconds, lost_seconds
        self.coordinator = None
        self.workers = {}

    def start_coordinator(self, *extra, data="data", cwd=None, token=True):
        self.coordinator = spawn("coordinator", "--grpc", self.addr, "--data",
                                 os.path.join(self.dir, data),
                                 "--lease-seconds", str(self.lease_seconds),
                                 "--lost-seconds", str(self.lost_seconds), *extra,
                                 *(["--http", f"127.0.0.1:{self.http_port}"]
                                   if self.http_port else []),
                                 log=os.path.join(self.dir, "coordinator.log"), cwd=cwd,
                                 token=token)
        # A coordinator that makes its own tokens has them before it listens.
        token_file = CLIENT_TOKEN if token else os.path.join(self.dir, data, "client.token")
        deadline = time.time() + 20
        while time.time() < deadline:
            if run("status", "--coordinator", self.addr, "--token-file", token_file,
                   check=False).returncode == 0:
                return
            time.sleep(0.1)
        raise AssertionError("coordinator did not start")

    def start_worker(self, name, threads=1, cwd=None):
        self.workers[name] = spawn("worker", "--coordinator", self.addr, "--threads",
                                   str(threads), "--name", name,
                                   log=os.path.join(self.dir, f"worker-{name}.log"), cwd=cwd)

    def log_lines(self, name):
        with open(os.path.join(self.dir, f"worker-{name}.log")) as f:
            return len(f.readlines())

    def workers_now(self):
        return {w["name"]: w for w in
                json.loads(run("workers", "--json", "--coordinator", self.addr).stdout)}

    def submit(self, *render_args, out=None):
        args = ["submit", "--coordinator", self.addr, "--json", *render_args]
        if out:
            args += ["--out", out]
        return json.loads(run(*args).stdout)

    def status(self, render_id):
        return json.loads(run("status", render_id, "--coordinator", self.addr, "--json").stdout)

    def wait_until(self, render_id, predicate, timeout=120):
        deadline = time.time() + timeout
        while time.time() < deadline:
            s = self.status(render_id)
            if predicate(s):
                return s
            time.sleep(0.05)
        raise AssertionError(f"timed out waiting on {render_id}: {s}")

    def stop(self):
        for p in list(self.workers.values()) + [self.coordinator]:
            if p and p.poll() is None:
                p.terminate()
        for p in list(self.workers.values()) + [self.coordinator]:
            if p:
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()


EMBEDDED = {}


def embedded(render_args):
    key = tuple(render_args)
    if key not in EMBEDDED:
        path = os.path.join(TMP, f"embedded-{len(EMBEDDED)}.exr")
        run("render", *render_args, "--threads", "2", "--out", path)
        EMBEDDED[key] = path
    return EMBEDDED[key]


SMALL = ["--scene", "cornell-box", "--resolution", "48x40", "--spp", "24", "--seed", "7"]
# Long enough (a few seconds on 2 cores) that things can happen in the middle of it.
LONG = ["--scene", "cornell-box", "--resolution", "96x96", "--spp", "512", "--seed", "11"]
# Uniform rounds of 455, 455 and 490 spp (the first holds about 2^22 samples).
THREE_ROUNDS = ["--scene", "cornell-box", "--resolution", "96x96", "--spp", "1400",
                "--seed", "11"]


def same(a, b):
    return filecmp.cmp(a, b, shallow=False)


def test_one_and_three_workers_match_embedded():
    for n in (1, 3):
        farm = Farm(f"workers-{n}")
        try:
            farm.start_coordinator()
            for i in range(n):
                farm.start_worker(f"w{i}")
            out = os.path.join(farm.dir, "farm.exr")
            info = farm.submit(*SMALL, out=out)
            assert info["state"] == "done", info
            assert same(out, embedded(SMALL)), f"{n} workers differ from embedded"
        finally:
            farm.stop()


def test_worker_killed_mid_round_still_matches():
    farm = Farm("kill-worker")
    try:
        farm.start_coordinator()
        farm.start_worker("doomed")
        farm.start_worker("survivor")
        render_id = farm.submit(*LONG)["id"]
        farm.wait_until(render_id, lambda s: s["samples_done"] > 0)
        farm.workers["doomed"].send_signal(signal.SIGKILL)
        farm.wait_until(render_id, lambda s: s["state"] == "done", timeout=300)
        out = os.path.join(farm.dir, "farm.exr")
        run("fetch", render_id, "--out", out, "--coordinator", farm.addr)
        assert same(out, embedded(LONG)), "render after a worker's death differs"
        workers = json.loads(run("workers", "--json", "--coordinator", farm.addr).stdout)
        time.sleep(farm.lost_seconds + 0.5)
        workers = json.loads(run("workers", "--json", "--coordinator", farm.addr).stdout)
        states = {w["name"]: w["state"] for w in workers}
        assert states["doomed"] == "lost", states
    finally:
        farm.stop()


def test_coordinator_restart_resumes_from_checkpoint():
    farm = Farm("restart")
    try:
        farm.start_coordinator()
        farm.start_worker("w0", threads=2)
        render_id = farm.submit(*THREE_ROUNDS)["id"]
        farm.wait_until(render_id, lambda s: s["rounds"] >= 2)
        farm.coordinator.send_signal(signal.SIGKILL)
        farm.coordinator.wait()
        farm.start_coordinator()
        resumed = farm.status(render_id)
        # Checkpoints are written at most a 20th of the time (docs/FARM.md): the restart
        # resumes from the last one, which may be a round or two behind the kill.
        assert resumed["rounds"] >= 1, f"restart did not resume from a checkpoint: {resumed}"
        final = farm.wait_until(render_id, lambda s: s["state"] == "done", timeout=300)
        out = os.path.join(farm.dir, "farm.exr")
        run("fetch", render_id, "--out", out, "--coordinator", farm.addr)
        assert same(out, embedded(THREE_ROUNDS)), "resumed render differs"
        db = sqlite3.connect(os.path.join(farm.dir, "data", "aliquot.db"))
        idx = [r[0] for r in db.execute(
            "SELECT idx FROM rounds WHERE render_id = ? ORDER BY idx", (render_id,))]
        assert idx == list(range(final["rounds"])), f"rounds in SQLite: {idx}"
    finally:
        farm.stop()


def test_twenty_concurrent_submissions_all_complete():
    farm = Farm("twenty")
    try:
        farm.start_coordinator()
        farm.start_worker("w0")
        farm.start_worker("w1")
        variants = [["--scene", "cornell-box", "--resolution", "16x12", "--spp", "8",
                     "--seed", str(100 + i)] for i in range(20)]

        def one(i):
            out = os.path.join(farm.dir, f"r{i}.exr")
            info = farm.submit(*variants[i], out=out)
            return info, out

        with concurrent.futures.ThreadPoolExecutor(20) as pool:
            results = list(pool.map(one, range(20)))
        for i, (info, out) in enumerate(results):
            assert info["state"] == "done", info
            assert same(out, embedded(variants[i])), f"render {i} differs from its twin"
        db = sqlite3.connect(os.path.join(farm.dir, "data", "aliquot.db"))
        done = db.execute("SELECT COUNT(*) FROM renders WHERE state = 'done'").fetchone()[0]
        assert done == 20, f"{done} renders done in SQLite"
        db.close()
        farm.stop()  # the coordinator writes its workers' last samples as it stops
        db = sqlite3.connect(os.path.join(farm.dir, "data", "aliquot.db"))
        traced = db.execute("SELECT SUM(samples_traced) FROM workers").fetchone()[0]
        assert traced == 20 * 16 * 12 * 8, f"workers traced {traced} samples in SQLite"
    finally:
        farm.stop()


def test_early_and_late_workers_get_work():
    farm = Farm("early-late")
    try:
        farm.start_worker("early")  # before any coordinator listens
        time.sleep(1.0)
        farm.start_coordinator()
        render_id = farm.submit(*LONG)["id"]
        farm.wait_until(render_id, lambda s: s["samples_done"] > 0)
        farm.start_worker("late")
        farm.wait_until(render_id, lambda s: s["state"] == "done", timeout=300)
        workers = json.loads(run("workers", "--json", "--coordinator", farm.addr).stdout)
        traced = {w["name"]: w["samples_traced"] for w in workers}
        assert traced.get("early", 0) > 0 and traced.get("late", 0) > 0, traced
    finally:
        farm.stop()


def test_full_hd_render_fits_in_messages():
    # 1920x1080: jobs and results must stay under gRPC's 4 MiB default message size.
    farm = Farm("full-hd")
    try:
        farm.start_coordinator()
        farm.start_worker("w0", threads=2)
        args = ["--scene", "cornell-box", "--resolution", "1920x1080", "--spp", "1", "--seed", "5"]
        out = os.path.join(farm.dir, "hd.exr")
        info = farm.submit(*args, out=out)
        assert info["state"] == "done" and info["samples_done"] == 1920 * 1080, info
        assert same(out, embedded(args)), "1920x1080 farm render differs from embedded"
    finally:
        farm.stop()


def test_client_errors_are_one_line():
    farm = Farm("errors")
    try:
        farm.start_coordinator()
        bad_scene = os.path.join(farm.dir, "bad.json")
        with open(bad_scene, "w") as f:
            f.write('{"camera": {"position": [0,0,1], "target": [0,0,0], "up": [0,1,0], '
                    '"fov": 500}, "materials": {}, "shapes": []}')
        # 2: the command line cannot be right; 1: running it failed (here the scene file).
        cases = [
            (["--scene", bad_scene], "/camera/fov", 1),
            (["--method", "magic"], "method", 2),
            (["--resolution", "0x10"], "--resolution", 2),
            (["--resolution", "9000x10"], "--resolution", 2),
            (["--method", "uniform", "--budget", "18446744073709551615"], "budget", 2),
        ]
        for args, expected, code in cases:
            r = run("submit", "--coordinator", farm.addr, *args, check=False)
            lines = r.stderr.strip().splitlines()
            assert r.returncode == code and len(lines) == 1 and expected in lines[0], (args, r)
        r = run("status", "--coordinator", f"127.0.0.1:{free_port()}", "--connect-timeout",
                "0.3", check=False)
        assert r.returncode == 1 and "cannot reach coordinator" in r.stderr, r.stderr
        assert "after waiting" in r.stderr, r.stderr
        assert len(r.stderr.strip().splitlines()) == 1, r.stderr
    finally:
        farm.stop()


def test_storage_warning_reaches_status_and_http():
    # The render's directory replaced by a file: its EXR cannot be written, for root as
    # for a user, as if the disk were full.
    farm = Farm("storage", http=True)
    warning_line = "warning: the coordinator cannot write its record: "

    def http_warning():
        url = f"http://127.0.0.1:{farm.http_port}/api/renders"
        request = urllib.request.Request(
            url, headers={"Authorization": "Bearer " + client_token()})
        with urllib.request.urlopen(request, timeout=10) as r:
            return json.load(r)["storage_warning"]

    try:
        farm.start_coordinator()
        render_id = farm.submit(*SMALL)["id"]
        render_dir = os.path.join(farm.dir, "data", "renders", render_id)
        shutil.rmtree(render_dir)
        with open(render_dir, "w") as f:
            f.write("not a directory")
        r = run("status", "--coordinator", farm.addr)
        assert warning_line not in r.stderr and http_warning() == "", r.stderr
        farm.start_worker("w0")
        farm.wait_until(render_id, lambda s: s["state"] == "done")
        r = run("status", "--coordinator", farm.addr)
        lines = [l for l in r.stderr.splitlines() if l.startswith(warning_line)]
        assert len(lines) == 1 and render_id in lines[0], r.stderr
        assert render_id in r.stdout, r.stdout
        r = run("status", render_id, "--json", "--coordinator", farm.addr)
        assert json.loads(r.stdout)["state"] == "done" and warning_line in r.stderr, r.stderr
        assert lines[0][len(warning_line):] == http_warning()
        # The disk takes writes again: the record is written and the warning goes.
        os.remove(render_dir)
        os.mkdir(render_dir)
        deadline = time.time() + 90
        while warning_line in run("status", "--coordinator", farm.addr).stderr:
            assert time.time() < deadline, "the warning stayed after the disk recovered"
            time.sleep(0.5)
        assert http_warning() == ""
        assert os.path.exists(os.path.join(render_dir, "image.exr"))
    finally:
        farm.stop()


def test_priorities_and_deleting_through_the_cli_and_http():
    # Issue 16: leases go to the highest priority first; a finished render can be
    # deleted (files, record), a running one cannot.
    farm = Farm("priority", http=True)

    def http(method, path, body=None):
        url = f"http://127.0.0.1:{farm.http_port}{path}"
        data = json.dumps(body).encode() if body is not None else None
        request = urllib.request.Request(url, data=data, method=method, headers={
            "Authorization": "Bearer " + client_token(), "Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(request, timeout=10) as r:
                text = r.read()
                return r.status, (json.loads(text) if text else None)
        except urllib.error.HTTPError as e:
            return e.code, json.loads(e.read() or b"null")

    try:
        farm.start_coordinator()
        unseeded = SMALL[:SMALL.index("--seed")]
        low = [farm.submit(*unseeded, "--seed", str(i))["id"] for i in range(10)]
        high = farm.submit(*SMALL, "--priority", "5")["id"]
        assert farm.status(high)["priority"] == 5
        # Raised over HTTP while queued; the CLI lowers one of the low ones.
        status, info = http("PATCH", f"/api/renders/{low[-1]}", {"priority": 7})
        assert status == 200 and info["priority"] == 7, (status, info)
        assert "priority 3" in run("priority", low[-1], "3", "--coordinator", farm.addr).stdout
        assert farm.status(low[-1])["priority"] == 3
        assert http("PATCH", f"/api/renders/{high}", {"priority": "x"})[0] == 400
        assert http("PATCH", "/api/renders/r-999999", {"priority": 1})[0] == 404
        farm.start_worker("w0")
        for render_id in low + [high]:
            farm.wait_until(render_id, lambda s: s["state"] == "done")
        finished = {r: farm.status(r)["finished_ms"] for r in low + [high]}
        others = min(finished[r] for r in low[:-1])
        assert finished[high] <= finished[low[-1]] <= others, finished
        # Deleting: a finished render goes with its files; a running one stays.
        long_id = farm.submit(*LONG)["id"]
        r = run("delete", long_id, "--coordinator", farm.addr, check=False)
        assert r.returncode != 0 and "cancel it first" in r.stderr, r.stderr
        assert http("DELETE", f"/api/renders/{long_id}")[0] == 409
        assert http("PATCH", f"/api/renders/{high}", {"priority": 1})[0] == 409
        render_dir = os.path.join(farm.dir, "data", "renders", high)
        assert os.path.exists(os.path.join(render_dir, "image.exr"))
        run("delete", high, "--coordinator", farm.addr)
        assert not os.path.exists(render_dir)
        r = run("status", high, "--coordinator", farm.addr, check=False)
        assert r.returncode != 0 and "no render" in r.stderr, r.stderr
        assert http("DELETE", f"/api/renders/{low[0]}")[0] == 204
        assert http("GET", f"/api/renders/{low[0]}")[0] == 404
        assert http("DELETE", f"/api/renders/{low[0]}")[0] == 404
        run("cancel", long_id, "--coordinator", farm.addr)
        run("delete", long_id, "--coordinator", farm.addr)
    finally:
        farm.stop()


def test_retention_deletes_finished_renders_through_the_coordinator_flag():
    # --keep-days as a fraction: 0.00002 days is 1.7 s.
    farm = Farm("retention")
    try:
        farm.start_coordinator("--keep-days", "0.00002")
        render_id = farm.submit(*SMALL)["id"]
        # Far longer than the test: it is still running when it ends.
        running = farm.submit("--scene", "cornell-box", "--resolution", "96x96", "--spp",
                              "8192", "--seed", "3")["id"]
        farm.start_worker("w0")
        farm.wait_until(render_id, lambda s: s["state"] == "done")
        render_dir = os.path.join(farm.dir, "data", "renders", render_id)
        deadline = time.time() + 60
        while run("status", render_id, "--coordinator", farm.addr, check=False).returncode == 0:
            assert time.time() < deadline, "the finished render was kept"
            time.sleep(0.2)
        assert not os.path.exists(render_dir)
        assert farm.status(running)["state"] in ("queued", "running"), "a live render went"
        run("cancel", running, "--coordinator", farm.addr)
    finally:
        farm.stop()


def content_hash(text):
    """coordinator/farm/render_spec.cpp's content_hash: the scene's content address."""
    mask = (1 << 64) - 1

    def mix64(z):
        z = ((z ^ (z >> 30)) * 0xbf58476d1ce4e5b9) & mask
        z = ((z ^ (z >> 27)) * 0x94d049bb133111eb) & mask
        return z ^ (z >> 31)

    data = text.encode()
    a = 0x243f6a8885a308d3 ^ len(data)
    b = (0x13198a2e03707344 + len(data)) & mask
    i = 0
    while i + 8 <= len(data):
        w = int.from_bytes(data[i:i + 8], "little")
        a = mix64(a ^ w)
        b = mix64((b + w * 0x9e3779b97f4a7c15) & mask)
        i += 8
    tail = int.from_bytes(data[i:], "little")
    a = mix64(a ^ tail ^ 0xa4093822299f31d0)
    b = mix64((b + tail + 0x082efa98ec4e6c89) & mask)
    return f"{a:016x}{b:016x}"


def test_a_job_no_worker_can_trace_fails_the_render():
    # Issue 12, item 5: a scene whose mesh file only exists beside the coordinator. The CLI
    # inlines meshes, so the render is made such in the store (as a scene recorded by an
    # older coordinator would be): its scene gains a mesh by relative path, which a worker
    # started in another directory cannot open. Before, every worker abandoned and
    # re-leased the job at once, thousands of log lines a second, the render running at 0
    # samples forever. Since issue 13 no worker opens a mesh file at all: each refuses the
    # scene's "file" by its JSON pointer, and the render fails the same way.
    farm = Farm("fail-everywhere")
    beside = os.path.join(farm.dir, "coordinator-cwd")
    elsewhere = os.path.join(farm.dir, "worker-cwd")
    os.makedirs(beside)
    os.makedirs(elsewhere)
    with open(os.path.join(beside, "tri.obj"), "w") as f:
        f.write("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\n")
    try:
        farm.start_coordinator(cwd=beside)
        render_id = farm.submit(*SMALL)["id"]
        farm.coordinator.send_signal(signal.SIGKILL)
        farm.coordinator.wait()
        db = sqlite3.connect(os.path.join(farm.dir, "data", "aliquot.db"))
        old_hash, = db.execute("SELECT scene_hash FROM renders WHERE id = ?",
                               (render_id,)).fetchone()
        text, = db.execute("SELECT json FROM scenes WHERE hash = ?", (old_hash,)).fetchone()
        assert content_hash(text) == old_hash, "content_hash differs from the coordinator's"
        scene = json.loads(text)
        scene["shapes"].append({"type": "mesh", "material": next(iter(scene["materials"])),
                                "file": "tri.obj"})
        new_text = json.dumps(scene)
        new_hash = content_hash(new_text)
        db.execute("INSERT INTO scenes (hash, name, json, created_at) "
                   "SELECT ?, name, ?, created_at FROM scenes WHERE hash = ?",
                   (new_hash, new_text, old_hash))
        db.execute("UPDATE renders SET scene_hash = ? WHERE id = ?", (new_hash, render_id))
        db.commit()
        db.close()

        # Issue 30, item 9: failures count per host, and these three workers are one
        # (127.0.0.1): by default one host never fails a render alone.
        farm.start_coordinator(cwd=beside)
        for name in ("w0", "w1", "w2"):
            farm.start_worker(name, cwd=elsewhere)

        def failures():
            return sum(open(os.path.join(farm.dir, f"worker-{n}.log")).read()
                       .count("cannot trace a job") for n in farm.workers)
        deadline = time.time() + 60
        while failures() < 4:
            assert time.time() < deadline, "the workers did not fail the job"
            time.sleep(0.2)
        state = run("status", render_id, "--json", "--coordinator", farm.addr).stdout
        assert json.loads(state)["state"] == "running", state
        # The operator says a farm of fewer hosts may fail a render.
        farm.coordinator.send_signal(signal.SIGTERM)
        farm.coordinator.wait()
        before = {n: farm.log_lines(n) for n in farm.workers}
        farm.start_coordinator("--fail-on-fewer-hosts", cwd=beside)
        start = time.time()
        final = farm.wait_until(render_id, lambda s: s["state"] != "running", timeout=60)
        took = time.time() - start
        assert final["state"] == "failed", final
        assert re.match(r"job \d+,\d+ \d+x\d+ failed \d+ times on 1 worker: "
                        r".*/shapes/\d+/file: mesh files are resolved by the client",
                        final["error"]), final["error"]
        assert final["samples_done"] == 0, final
        print(f"     failed in {took:.1f}s: {final['error']}", flush=True)
        assert took < 20, f"the render took {took:.1f}s to fail"
        # Bounded work and logs: a few lines per worker, and none once the render failed.
        # A worker still in its reconnect back-off when the render failed registers after
        # it ("registered again", then "coordinator back" once a lease call answers): that
        # is not work, so wait for every worker to say it is back before counting.
        def back(n):
            with open(os.path.join(farm.dir, f"worker-{n}.log")) as f:
                return "coordinator back" in "".join(f.readlines()[before[n]:])
        deadline = time.time() + 30
        while not all(back(n) for n in farm.workers):
            assert time.time() < deadline, "a worker did not come back"
            time.sleep(0.2)
        lines = {n: farm.log_lines(n) for n in farm.workers}
        assert all(lines[n] - before[n] <= 10 for n in lines), (before, lines)
        time.sleep(2)
        assert {n: farm.log_lines(n) for n in farm.workers} == lines, "workers still logging"
        assert all(p.poll() is None for p in farm.workers.values()), "a worker died"
        text = run("status", render_id, "--coordinator", farm.addr).stdout
        assert "failed" in text and "resolved by the client" in text, text
        r = run("watch", render_id, "--coordinator", farm.addr, check=False)
        assert r.returncode == 1 and "failed" in r.stderr.splitlines()[-1], r
        db = sqlite3.connect(os.path.join(farm.dir, "data", "aliquot.db"))
        state, error = db.execute("SELECT state, error FROM renders WHERE id = ?",
                                  (render_id,)).fetchone()
        db.close()
        assert state == "failed" and error == final["error"], (state, error)
        # The workers still serve a render they can trace.
        out = os.path.join(farm.dir, "after.exr")
        info = farm.submit(*SMALL, out=out)
        assert info["state"] == "done" and same(out, embedded(SMALL)), info
    finally:
        farm.stop()


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    raise AssertionError("no VmRSS")


# Issue 12, item 7: finished renders' buffers stayed in memory; 20 submit-and-cancel
# cycles at 1024x1024 took the coordinator from 24 MB to 2.1 GB. One such render holds
# about 110 MB (96 bytes a pixel of accumulator, a round's jobs) while it lives, and as
# much again for its checkpoint copy once the backlog has prepared it (not for a render
# already cancelled); cancelled, it leaves memory once its image is written. 300 MB leaves room for the process itself and
# two renders in flight at once, and is a seventh of what 20 kept renders took.
def test_cancelled_renders_give_their_memory_back():
    farm = Farm("memory")
    try:
        farm.start_coordinator()
        ids = []
        for _ in range(20):
            rid = farm.submit("--scene", "cornell-box", "--resolution", "1024x1024",
                              "--spp", "4")["id"]
            run("cancel", rid, "--coordinator", farm.addr)
            ids.append(rid)
        for rid in ids:
            farm.wait_until(rid, lambda s: s["state"] == "cancelled")
        deadline = time.time() + 20
        while rss_mb(farm.coordinator.pid) >= 300 and time.time() < deadline:
            time.sleep(0.2)
        rss = rss_mb(farm.coordinator.pid)
        assert rss < 300, f"coordinator holds {rss:.0f} MB after 20 cancelled 1024x1024 renders"
        # Their images are read back from disk.
        out = os.path.join(farm.dir, "last.exr")
        run("fetch", ids[-1], "--coordinator", farm.addr, "--out", out)
        assert os.path.getsize(out) > 0
    finally:
        farm.stop()


def test_a_submission_past_the_memory_limit_is_one_line():
    farm = Farm("memory-limit")
    try:
        farm.start_coordinator("--memory-limit", "64M")
        r = run("submit", "--coordinator", farm.addr, "--scene", "cornell-box",
                "--resolution", "1024x1024", "--spp", "4", check=False)
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 1 and len(lines) == 1, r.stderr
        assert "not enough memory" in lines[0] and "64.0 MiB" in lines[0], r.stderr
        # A small one still fits.
        farm.submit(*SMALL)
    finally:
        farm.stop()


def test_a_worker_registers_again_after_a_coordinator_restart():
    # Issue 12, item 9: after a coordinator restart the worker never registered again
    # (`workers` showed threads: 0), and took ~10 s to come back after a SIGTERM.
    farm = Farm("re-register")
    try:
        farm.start_coordinator()
        farm.start_worker("w0", threads=2)
        deadline = time.time() + 20
        while farm.workers_now().get("w0", {}).get("threads", 0) != 2:
            assert time.time() < deadline, farm.workers_now()
            time.sleep(0.1)
        farm.coordinator.send_signal(signal.SIGTERM)
        farm.coordinator.wait(timeout=20)
        time.sleep(4)  # the worker retries meanwhile; its waits must not grow long
        farm.start_coordinator(data="data-2")
        up = time.time()
        while farm.workers_now().get("w0", {}).get("threads", 0) != 2:
            assert time.time() - up < 10, f"worker not back with its threads: {farm.workers_now()}"
            time.sleep(0.05)
        back = time.time() - up
        print(f"     worker back with its threads {back:.2f}s after the coordinator", flush=True)
        out = os.path.join(farm.dir, "farm.exr")
        info = farm.submit(*SMALL, out=out)
        assert info["state"] == "done", info
        assert same(out, embedded(SMALL)), "render after the restart differs from embedded"
    finally:
        farm.stop()


def write_grid_scene(folder, n=225):
    """A scene whose mesh is an OBJ of an n x n vertex grid (2 (n-1)^2 triangles: 100352
    for 225), a rippled floor under a light, named by a path relative to the scene."""
    os.makedirs(os.path.join(folder, "meshes"), exist_ok=True)
    lines = ["# generated by farm_test.py"]
    for j in range(n):
        for i in range(n):
            x, y = 2 * i / (n - 1) - 1, 2 * j / (n - 1) - 1
            z = 0.05 * ((i * 7 + j * 13) % 17) / 17
            lines.append(f"v {x:.6f} {y:.6f} {z:.6f}")
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i + 1
            lines.append(f"f {a} {a + 1} {a + n + 1} {a + n}")
    with open(os.path.join(folder, "meshes", "grid.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    scene = {
        "camera": {"position": [0, -2.2, 2.2], "target": [0, 0, 0], "up": [0, 0, 1],
                   "fov": 45},
        "materials": {"white": {"type": "diffuse", "reflectance": 0.7}},
        "shapes": [
            {"type": "rectangle", "material": "white", "emission": 4,
             "transform": {"translate": [0, 0, 1.5], "rotate": ["x", 180], "scale": 0.5}},
            {"type": "mesh", "material": "white", "file": "meshes/grid.obj",
             "transform": {"rotate": ["z", 10]}},
        ],
    }
    path = os.path.join(folder, "grid.json")
    with open(path, "w") as f:
        json.dump(scene, f)
    return path


def test_a_mesh_scene_submitted_from_elsewhere_matches_a_local_render():
    """Issue 13: the client inlines a 100k-triangle OBJ; the coordinator and worker run in
    a directory where the mesh's relative path names nothing, open no file, and the farm's
    EXR is the bytes of `aliquot render` of the same scene file."""
    farm = Farm("mesh-inline")
    elsewhere = os.path.join(farm.dir, "server-cwd")
    client = os.path.join(farm.dir, "client-cwd")
    os.makedirs(elsewhere)
    os.makedirs(client)
    scene = write_grid_scene(os.path.join(farm.dir, "scene"))
    args = ["--scene", os.path.relpath(scene, client), "--resolution", "40x32", "--spp", "8",
            "--seed", "3"]
    try:
        farm.start_coordinator(cwd=elsewhere)
        farm.start_worker("w0", threads=2, cwd=elsewhere)
        out = os.path.join(farm.dir, "farm.exr")
        r = subprocess.run([ALIQUOT, "submit", "--coordinator", farm.addr, "--json", *args,
                            "--out", out, "--token-file", CLIENT_TOKEN],
                           capture_output=True, text=True, timeout=300, cwd=client)
        assert r.returncode == 0, r.stderr
        assert json.loads(r.stdout)["state"] == "done", r.stdout
        local = os.path.join(farm.dir, "local.exr")
        r = subprocess.run([ALIQUOT, "render", *args, "--threads", "2", "--out", local],
                           capture_output=True, text=True, timeout=300, cwd=client)
        assert r.returncode == 0, r.stderr
        assert same(out, local), "the farm's render of the mesh scene differs from the local one"
    finally:
        farm.stop()


def test_tokens_made_by_the_coordinator_admit_each_role_only():
    """Issue 13: a coordinator without token files makes both, private to its user; each
    role's token works for that role only, a missing one is refused, and a worker handed
    the client token stops with the reason instead of retrying for ever."""
    farm = Farm("tokens")
    data = os.path.join(farm.dir, "data")
    client, worker = os.path.join(data, "client.token"), os.path.join(data, "worker.token")
    try:
        farm.start_coordinator(token=False)
        for path in (client, worker):
            assert os.stat(path).st_mode & 0o777 == 0o600, oct(os.stat(path).st_mode)
        with open(client) as f:
            secret = f.read().strip()
        r = run("status", "--coordinator", farm.addr, "--token-file", client)
        assert r.returncode == 0, r.stderr
        r = run("status", "--coordinator", farm.addr, "--token-file", worker, check=False)
        assert r.returncode == 1 and "client token" in r.stderr, r.stderr
        r = run("submit", "--coordinator", farm.addr, *SMALL, "--token-file", CLIENT_TOKEN,
                check=False)
        assert r.returncode == 1 and "client token" in r.stderr, r.stderr
        assert secret not in r.stderr
        empty = os.path.join(farm.dir, "empty")
        os.makedirs(empty)
        r = subprocess.run([ALIQUOT, "status", "--coordinator", farm.addr,
                            "--connect-timeout", "0"],
                           capture_output=True, text=True, timeout=60, cwd=empty,
                           env={k: v for k, v in os.environ.items() if k != "ALIQUOT_TOKEN"})
        assert r.returncode == 1 and "--token-file" in r.stderr, r.stderr
        r = subprocess.run([ALIQUOT, "status", "--coordinator", farm.addr],
                           capture_output=True, text=True, timeout=60, cwd=empty,
                           env={**os.environ, "ALIQUOT_TOKEN": secret})
        assert r.returncode == 0, r.stderr
        # A worker with the client token is refused at registration and exits 1 by itself.
        w = subprocess.run([ALIQUOT, "worker", "--coordinator", farm.addr, "--threads", "1",
                            "--token-file", client], capture_output=True, text=True,
                           timeout=60)
        assert w.returncode == 1 and "worker token" in w.stderr, w.stderr
        r = run("workers", "--json", "--coordinator", farm.addr, "--token-file", client)
        assert json.loads(r.stdout) == [], r.stdout
    finally:
        farm.stop()


def clean_env(**extra):
    """The environment without the variables a client reads, plus `extra`."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("ALIQUOT_TOKEN", "ALIQUOT_COORDINATOR")}
    return {**env, **extra}


def test_clients_started_with_the_coordinator_wait_for_it():
    """Issue 16: `aliquot coordinator & aliquot worker & aliquot submit`, no sleep between
    them, in one directory: the worker and the client wait for the token files the
    coordinator writes and for its port, within --connect-timeout. The client goes first,
    so it starts before there is anything to reach. The address comes from
    ALIQUOT_COORDINATOR."""
    farm = Farm("no-sleep")
    env = clean_env(ALIQUOT_COORDINATOR=farm.addr)
    out = os.path.join(farm.dir, "farm.exr")
    log = os.path.join(farm.dir, "coordinator.log")
    try:
        client = subprocess.Popen([ALIQUOT, "submit", *SMALL, "--json", "--out", out],
                                  cwd=farm.dir, env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        PROCS.append(client)
        farm.coordinator = subprocess.Popen([ALIQUOT, "coordinator", "--grpc", farm.addr],
                                            cwd=farm.dir, env=env, stdout=open(log, "w"),
                                            stderr=subprocess.STDOUT)
        PROCS.append(farm.coordinator)
        farm.workers["w0"] = subprocess.Popen(
            [ALIQUOT, "worker", "--threads", "2", "--name", "w0"], cwd=farm.dir, env=env,
            stdout=open(os.path.join(farm.dir, "worker-w0.log"), "w"),
            stderr=subprocess.STDOUT)
        PROCS.append(farm.workers["w0"])
        stdout, stderr = client.communicate(timeout=300)
        assert client.returncode == 0, stderr
        info = json.loads(stdout)
        assert info["state"] == "done" and info["seed"] == "7", info
        assert same(out, embedded(SMALL)), "the render differs from embedded"
    finally:
        farm.stop()


def test_watch_says_how_a_render_ended():
    """watch exits 0 for a done render and 1 for a cancelled one, as submit --wait does."""
    farm = Farm("watch")
    try:
        farm.start_coordinator()
        render_id = farm.submit(*LONG)["id"]  # no worker: it stays running
        run("cancel", render_id, "--coordinator", farm.addr)
        r = run("watch", render_id, "--coordinator", farm.addr, check=False)
        assert r.returncode == 1 and "cancelled" in r.stderr.splitlines()[-1], r
        farm.start_worker("w0")
        done = farm.submit(*SMALL)["id"]
        r = run("watch", done, "--coordinator", farm.addr, check=False)
        assert r.returncode == 0, r
    finally:
        farm.stop()


def test_cli_and_http_speak_the_same_json():
    """Issue 16: one vocabulary. A render and the workers as `--json` prints them and as the
    HTTP API serves them; the EXR from HTTP is the bytes `fetch --aovs` writes."""
    farm = Farm("vocabulary", http=True)

    def http(path):
        request = urllib.request.Request(
            f"http://127.0.0.1:{farm.http_port}{path}",
            headers={"Authorization": "Bearer " + client_token()})
        with urllib.request.urlopen(request, timeout=60) as r:
            return r.read(), r.headers

    try:
        farm.start_coordinator()
        farm.start_worker("w0")
        big_seed = str(2**64 - 1)
        args = [*SMALL[:-1], big_seed]
        cli = farm.submit(*args, out=os.path.join(farm.dir, "cli.exr"))
        assert cli["seed"] == big_seed, cli
        api = json.loads(http(f"/api/renders/{cli['id']}")[0])
        status = farm.status(cli["id"])
        # The HTTP API adds the farm's storage warning; everything else is the same.
        api.pop("storage_warning")
        assert set(api) == set(status), (set(api) ^ set(status))
        for key in ("id", "scene", "method", "state", "seed", "samples_done", "rounds",
                    "strategy"):
            assert api[key] == status[key], (key, api[key], status[key])
        workers_cli = json.loads(run("workers", "--json", "--coordinator", farm.addr).stdout)
        workers_api = json.loads(http("/api/workers")[0])["workers"]
        assert [set(w) for w in workers_cli] == [set(w) for w in workers_api], workers_cli

        fetched = os.path.join(farm.dir, "fetched.exr")
        run("fetch", cli["id"], "--aovs", "--out", fetched, "--coordinator", farm.addr)
        body, headers = http(f"/api/renders/{cli['id']}/image.exr?aovs=1")
        assert headers["Content-Type"] == "image/x-exr", headers
        with open(fetched, "rb") as f:
            assert f.read() == body, "the HTTP download differs from aliquot fetch"
        try:
            http("/api/renders/r-999999/image.exr")
            raise AssertionError("an unknown render's EXR was served")
        except urllib.error.HTTPError as e:
            assert e.code == 404, e
    finally:
        farm.stop()


def main(namespace=None):
    """Runs every test_* function of `namespace` (this module's by default; the ops suite
    passes its own), or those whose name contains $FARM_TEST."""
    namespace = globals() if namespace is None else namespace
    tests = [(n, f) for n, f in sorted(namespace.items()) if n.startswith("test_")]
    only = os.environ.get("FARM_TEST")
    passed = failed = 0
    for name, fn in tests:
        if only and only not in name:
            continue
        start = time.time()
        try:
            fn()
            passed += 1
            print(f"ok   {name} ({time.time() - start:.1f}s)", flush=True)
        except Exception as e:  # report and go on: one failure should not hide the others
            failed += 1
            print(f"FAIL {name}: {e!r}", flush=True)
    for p in PROCS:
        if p.poll() is None:
            p.kill()
    if failed == 0:
        shutil.rmtree(TMP, ignore_errors=True)
    else:
        print(f"logs kept in {TMP}")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
