"""A coordinator and its workers, each on a host of a `Network`, Toxiproxy before the port.

The coordinator listens on its namespace's loopback only (COORDINATOR_PORT), so a worker
reaches it through Toxiproxy (PROXY_PORT on the coordinator host's eth0), across the
bridge, and every byte of its calls crosses the delay; the test's own clients (submit,
status, fetch) run in the coordinator's namespace and go straight to the port. With
`through="loopback"` the workers run in the coordinator's namespace too and call its port
directly, with no proxy: the loopback farm the network is measured against.
"""
import json
import os
import signal
import subprocess
import time

from toxiproxy import Toxiproxy

COORDINATOR_PORT = 7000
PROXY_PORT = 7100
CLIENT_COMMANDS = {"submit", "status", "watch", "fetch", "cancel", "workers"}


class NetFarm:
    def __init__(self, network, aliquot, toxiproxy_server, tmp, lease_seconds=2.0,
                 lost_seconds=3.0, through="proxy"):
        self.network, self.aliquot, self.tmp = network, aliquot, tmp
        self.toxiproxy_server = toxiproxy_server
        self.lease_seconds, self.lost_seconds = lease_seconds, lost_seconds
        self.through = through
        self.data = os.path.join(tmp, "data")
        self.local = f"127.0.0.1:{COORDINATOR_PORT}"
        self.proxy = None
        self.coordinator = None
        self.workers = {}

    def _log(self, name):
        return open(os.path.join(self.tmp, f"{name}.log"), "a")

    def client(self, *args, check=True, timeout=120):
        """An aliquot client command in the coordinator's namespace, straight to its port."""
        args = list(args)
        if args[0] in CLIENT_COMMANDS:
            args += ["--coordinator", self.local, "--token-file",
                     os.path.join(self.data, "client.token")]
        r = subprocess.run(self.network.command("coordinator", [self.aliquot, *args]),
                           capture_output=True, text=True, timeout=timeout)
        if check and r.returncode != 0:
            raise AssertionError(f"aliquot {' '.join(args)} failed: {r.stderr.strip()}")
        return r

    def start(self, one_way_ms=0, jitter_ms=0, seed=1):
        self.coordinator = subprocess.Popen(
            self.network.command("coordinator", [
                self.aliquot, "coordinator", "--grpc", self.local, "--data", self.data,
                "--lease-seconds", str(self.lease_seconds),
                "--lost-seconds", str(self.lost_seconds)]),
            stdout=self._log("coordinator"), stderr=subprocess.STDOUT)
        deadline = time.time() + 30
        while self.client("status", "--json", check=False).returncode != 0:
            if self.coordinator.poll() is not None:
                raise AssertionError(f"coordinator exited with {self.coordinator.returncode}")
            if time.time() > deadline:
                raise AssertionError("coordinator did not answer within 30 s")
            time.sleep(0.1)
        if self.through == "proxy":
            self.proxy = Toxiproxy(self.network, "coordinator", self.toxiproxy_server,
                                   self._log("toxiproxy"), seed)
            self.proxy.proxy("coordinator",
                             f"{self.network.address('coordinator')}:{PROXY_PORT}",
                             self.local)
            if one_way_ms or jitter_ms:
                self.proxy.delay("coordinator", one_way_ms, jitter_ms)

    def start_worker(self, host, threads=1):
        if self.through == "proxy":
            addr, where = f"{self.network.address('coordinator')}:{PROXY_PORT}", host
        else:
            addr, where = self.local, "coordinator"
        self.workers[host] = subprocess.Popen(
            self.network.command(where, [
                self.aliquot, "worker", "--coordinator", addr, "--threads", str(threads),
                "--name", host, "--token-file", os.path.join(self.data, "worker.token")]),
            stdout=self._log(f"worker-{host}"), stderr=subprocess.STDOUT)

    def submit(self, *spec):
        return json.loads(self.client("submit", "--json", *spec).stdout)["id"]

    def status(self, render_id):
        return json.loads(self.client("status", render_id, "--json").stdout)

    def workers_now(self):
        return {w["name"]: w for w in json.loads(self.client("workers", "--json").stdout)}

    def check_alive(self):
        """No process of the farm may end on its own: the network must not kill one."""
        for name, p in [("coordinator", self.coordinator), *self.workers.items()]:
            if p is not None and p.poll() is not None:
                raise AssertionError(f"{name} exited on its own with {p.returncode}; see "
                                     f"{name}.log in {self.tmp}")
        if self.proxy and self.proxy.process.poll() is not None:
            raise AssertionError(f"toxiproxy-server exited with {self.proxy.process.returncode}")

    def stop(self):
        """SIGTERM to every process, SIGKILL to what has not ended 5 s later (a worker cut
        off cannot give its leases back: it would wait)."""
        procs = [*self.workers.values(), self.coordinator]
        for p in procs:
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs:
            if p is None:
                continue
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if self.proxy:
            self.proxy.stop()
