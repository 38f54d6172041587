"""A farm's network made of namespaces: one per host, veth pairs to a bridge, iptables inside.

Every host (the coordinator's, each worker's) is a network namespace of its own with one
interface, eth0, whose other end is a port of a bridge in a hub namespace. Nothing is made in
the machine's own namespace, and the hosts' addresses are in 198.18.0.0/24 (RFC 2544's range
for benchmark networks) on a bridge with no way out: no packet of the test leaves it.
Loss and partitions are iptables rules inside a host's namespace, so they go with it.

Names carry the test's pid (`aqnet<pid>-<host>`), so a run killed with SIGKILL, which no
handler sees, is cleaned up by the next run (`clean_stale`).
"""
import os
import signal
import subprocess

PREFIX = "aqnet"
SUBNET = "198.18.0"


def ip(*args, check=True):
    r = subprocess.run(["ip", *args], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip()}")
    return r.stdout


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
        return True
    except ProcessLookupError:
        return False
    except PermissionError:
        return True


def _delete_namespace(ns):
    """Kills what still runs in it (a namespace outlives its processes' deletion otherwise),
    then deletes it, and its iptables rules and interfaces with it."""
    for line in ip("netns", "pids", ns, check=False).split():
        try:
            os.kill(int(line), signal.SIGKILL)
        except (ValueError, ProcessLookupError):
            pass
    ip("netns", "del", ns, check=False)


def _namespaces():
    return [line.split()[0] for line in ip("netns", "list", check=False).splitlines() if line]


def clean_stale():
    """Namespaces of earlier runs of this test whose process is gone."""
    for ns in _namespaces():
        if not ns.startswith(PREFIX):
            continue
        pid = ns[len(PREFIX):].split("-", 1)[0]
        if pid.isdigit() and not _pid_alive(int(pid)):
            _delete_namespace(ns)


class Network:
    def __init__(self, hosts):
        """hosts: names; the first is given SUBNET.1, the next .2, and so on."""
        self.tag = f"{PREFIX}{os.getpid()}"
        self.hub = f"{self.tag}-hub"
        self.hosts = {name: (f"{self.tag}-{name}", f"{SUBNET}.{i + 1}")
                      for i, name in enumerate(hosts)}

    def up(self):
        ip("netns", "add", self.hub)
        ip("-n", self.hub, "link", "add", "br0", "type", "bridge")
        ip("-n", self.hub, "link", "set", "br0", "up")
        for i, (ns, address) in enumerate(self.hosts.values()):
            ip("netns", "add", ns)
            ip("-n", self.hub, "link", "add", f"port{i}", "type", "veth", "peer", "name",
               "eth0", "netns", ns)
            ip("-n", self.hub, "link", "set", f"port{i}", "master", "br0", "up")
            ip("-n", ns, "addr", "add", f"{address}/24", "dev", "eth0")
            ip("-n", ns, "link", "set", "eth0", "up")
            ip("-n", ns, "link", "set", "lo", "up")

    def down(self):
        for ns, _ in self.hosts.values():
            _delete_namespace(ns)
        _delete_namespace(self.hub)

    def address(self, host):
        return self.hosts[host][1]

    def command(self, host, argv):
        """argv run inside host's namespace (`ip netns exec` execs it: same pid)."""
        return ["ip", "netns", "exec", self.hosts[host][0], *argv]

    def _iptables(self, host, *args):
        r = subprocess.run(self.command(host, ["iptables", "-w", *args]), capture_output=True,
                           text=True)
        if r.returncode != 0:
            raise RuntimeError(f"iptables {' '.join(args)} on {host}: {r.stderr.strip()}")
        return r.stdout

    LOSS = ["-m", "statistic", "--mode", "random"]

    def lose(self, host, probability):
        """Drops each packet in or out of host's eth0 with this probability."""
        for chain, way in (("INPUT", "-i"), ("OUTPUT", "-o")):
            self._iptables(host, "-A", chain, way, "eth0", *self.LOSS, "--probability",
                           str(probability), "-j", "DROP")

    def partition(self, host):
        """Drops every packet in or out of host's eth0, ahead of any other rule."""
        for chain, way in (("INPUT", "-i"), ("OUTPUT", "-o")):
            self._iptables(host, "-I", chain, "1", way, "eth0", "-j", "DROP")

    def heal(self, host):
        for chain, way in (("INPUT", "-i"), ("OUTPUT", "-o")):
            self._iptables(host, "-D", chain, way, "eth0", "-j", "DROP")

    def dropped(self, host):
        """Packets dropped by host's rules so far, per rule: {'INPUT loss': n, ...}."""
        counts = {}
        for chain in ("INPUT", "OUTPUT"):
            for line in self._iptables(host, "-L", chain, "-v", "-x", "-n").splitlines()[2:]:
                fields = line.split()
                if len(fields) > 2 and fields[2] == "DROP":
                    kind = "loss" if "statistic" in line else "partition"
                    key = f"{chain} {kind}"
                    counts[key] = counts.get(key, 0) + int(fields[0])
        return counts
