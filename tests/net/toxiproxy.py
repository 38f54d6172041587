"""Toxiproxy in the coordinator's namespace: latency and jitter on the way to its port.

This machine's kernel has no netem qdisc, so delay comes from Shopify's Toxiproxy, a TCP
proxy that holds each chunk of a stream back by a latency plus a uniform jitter (chunks stay
in order: TCP's ordering is kept). scripts/install-deps.sh builds it into build/tools.
Its HTTP API listens on the namespace's loopback, so it is asked with curl run there.
"""
import json
import subprocess
import time

API_PORT = 8474


class Toxiproxy:
    def __init__(self, network, host, server, log, seed):
        self.network, self.host = network, host
        self.process = subprocess.Popen(
            network.command(host, [server, "-host", "127.0.0.1", "-port", str(API_PORT),
                                   "-seed", str(seed)]),
            stdout=log, stderr=subprocess.STDOUT)
        deadline = time.time() + 20
        while self._call("GET", "/version", check=False) is None:
            if self.process.poll() is not None:
                raise RuntimeError(f"toxiproxy-server exited with {self.process.returncode}")
            if time.time() > deadline:
                raise RuntimeError("toxiproxy-server did not answer within 20 s")
            time.sleep(0.1)

    def _call(self, method, path, body=None, check=True):
        argv = ["curl", "-sS", "--fail", "-X", method, f"http://127.0.0.1:{API_PORT}{path}"]
        if body is not None:
            argv += ["-H", "Content-Type: application/json", "-d", json.dumps(body)]
        r = subprocess.run(self.network.command(self.host, argv), capture_output=True,
                           text=True)
        if r.returncode != 0:
            if check:
                raise RuntimeError(f"toxiproxy {method} {path}: {r.stderr.strip()}")
            return None
        return r.stdout

    def proxy(self, name, listen, upstream):
        self._call("POST", "/proxies", {"name": name, "listen": listen, "upstream": upstream,
                                        "enabled": True})

    def delay(self, name, one_way_ms, jitter_ms):
        """Each direction held back by one_way_ms ± jitter_ms: a round trip of twice that."""
        for stream in ("upstream", "downstream"):
            self._call("POST", f"/proxies/{name}/toxics",
                       {"name": f"latency_{stream}", "type": "latency", "stream": stream,
                        "toxicity": 1.0,
                        "attributes": {"latency": one_way_ms, "jitter": jitter_ms}})

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
