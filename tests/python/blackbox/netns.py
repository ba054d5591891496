"""A LAN of network namespaces for the black-box tests (root only): a bridge on the host and one
namespace per node, each joined to the bridge by a veth pair, with an address in a /24 of its own,
so that a broadcast reaches every node as on a Wi-Fi network. Partitions are made by taking a
node's link down (its veth on the bridge side) or by splitting the bridge in two. Everything is set up and torn down by the test
that uses it; names carry the process id, so runs side by side do not meet."""

from __future__ import annotations

import os
import random
import subprocess

import pytest


def available() -> str | None:
    """None when namespaces can be made here, else why not."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    name = f"ev3probe{os.getpid() % 100000}"
    p = subprocess.run(["ip", "netns", "add", name], capture_output=True, text=True)
    if p.returncode != 0:
        return f"ip netns add failed: {p.stderr.strip()}"
    subprocess.run(["ip", "netns", "del", name], capture_output=True)
    return None


def lan_or_skip(n: int):
    """A pytest fixture's body: a Lan of @p n nodes, closed afterwards. Only a user who cannot make
    namespaces (not root) is skipped, saying so; as root (CI) a failure to make them fails."""
    if os.geteuid() != 0:
        pytest.skip("network namespaces need root")
    why = available()
    assert why is None, why
    lan = Lan(n)
    yield lan
    lan.close()


def _ip(*args: str) -> None:
    p = subprocess.run(["ip", *args], capture_output=True, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {p.stderr.strip()}")


class Lan:
    """@p n nodes on one bridge. Node i (0-based) is namespace ns(i) with address addr(i)."""

    def __init__(self, n: int) -> None:
        self.tag = f"{os.getpid() % 100000:05d}{random.randrange(100):02d}"   # interface names <= 15 bytes
        self.subnet = f"10.{random.randrange(64, 250)}.{random.randrange(1, 250)}"
        self.bridge = f"eb{self.tag}"
        self.other = f"ec{self.tag}"
        self.n = n
        self._made: list[tuple[str, str]] = []
        try:
            _ip("link", "add", self.bridge, "type", "bridge")
            self._made.append(("link", self.bridge))
            _ip("link", "set", self.bridge, "up")
            _ip("link", "add", self.other, "type", "bridge")  # split() moves nodes onto it
            self._made.append(("link", self.other))
            _ip("link", "set", self.other, "up")
            for i in range(n):
                ns, host, peer = self.ns(i), self.host_if(i), f"ep{self.tag}{i}"
                _ip("netns", "add", ns)
                self._made.append(("netns", ns))
                _ip("link", "add", host, "type", "veth", "peer", "name", peer)
                self._made.append(("link", host))
                _ip("link", "set", peer, "netns", ns)
                _ip("link", "set", host, "master", self.bridge)
                _ip("link", "set", host, "up")
                _ip("-n", ns, "link", "set", "lo", "up")
                _ip("-n", ns, "addr", "add", f"{self.addr(i)}/24", "brd", self.broadcast(), "dev", peer)
                _ip("-n", ns, "link", "set", peer, "up")
        except Exception:
            self.close()
            raise

    def ns(self, i: int) -> str:
        return f"ev3{self.tag}n{i}"

    def host_if(self, i: int) -> str:
        return f"eh{self.tag}{i}"

    def addr(self, i: int) -> str:
        return f"{self.subnet}.{i + 1}"

    def broadcast(self) -> str:
        return f"{self.subnet}.255"

    def argv(self, i: int, argv: list[str]) -> list[str]:
        """@p argv run inside node i's namespace."""
        return ["ip", "netns", "exec", self.ns(i), *argv]

    def link(self, i: int, up: bool) -> None:
        """Node i's link up or down (down: it hears nobody and nobody hears it)."""
        _ip("link", "set", self.host_if(i), "up" if up else "down")

    def split(self, side: list[int]) -> None:
        """The bridge split in two: the nodes @p side on a second bridge of their own, so each side
        hears only itself (broadcast included), until heal()."""
        for i in side:
            _ip("link", "set", self.host_if(i), "master", self.other)

    def heal(self) -> None:
        """Every node back on the one bridge."""
        for i in range(self.n):
            _ip("link", "set", self.host_if(i), "master", self.bridge)

    def close(self) -> None:
        for kind, name in reversed(self._made):
            subprocess.run(["ip", kind, "del", name], capture_output=True)
        self._made.clear()
