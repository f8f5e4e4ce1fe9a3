"""Test helpers for the bus: a free loopback port, a unique namespace, waiting, the process's sockets.

Every bus test opens real Zenoh sessions on 127.0.0.1 with its own port and namespace, so tests
can run in parallel with each other and with a simbot server on the default port.
"""

from __future__ import annotations

import itertools
import os
import socket
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from simbot.bus import BusOptions, Node

_counter = itertools.count()
TCP_LISTEN = "0A"


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def unique_namespace() -> str:
    """A namespace no other test (or running server) uses."""
    return f"test_{os.getpid()}_{next(_counter)}_{uuid.uuid4().hex[:6]}"


def endpoint(port: int) -> str:
    """The Zenoh TCP endpoint on loopback at `port`."""
    return f"tcp/127.0.0.1:{port}"


def wait_until(condition: Callable[[], object], timeout: float = 5.0, what: str = "condition") -> None:
    """Poll `condition` until it is true; AssertionError naming `what` after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.005)


@dataclass(frozen=True)
class Pair:
    """A server-role node and a client-role node connected to it on a fresh port and namespace."""

    server: Node
    client: Node
    port: int


@contextmanager
def node_pair(connect_timeout: float = 5.0) -> Iterator[Pair]:
    """Open a server node on a free loopback port and a client node connected to it."""
    port = free_port()
    namespace = unique_namespace()
    with Node(BusOptions(listen=(endpoint(port),), namespace=namespace), "server") as server:
        client_options = BusOptions(connect=(endpoint(port),), namespace=namespace, connect_timeout=connect_timeout)
        with Node(client_options, "client") as client:
            yield Pair(server, client, port)


@dataclass(frozen=True)
class BoundSocket:
    """A socket of this process: protocol, local address, and TCP state (0A = listening)."""

    proto: str
    address: str
    port: int
    state: str

    @property
    def loopback(self) -> bool:
        """Bound to 127.0.0.0/8 or ::1 (or an IPv4-mapped loopback)."""
        return self.address.startswith("127.") or self.address in ("::1", "::ffff:127.0.0.1")


def _hex_address(text: str, proto: str) -> tuple[str, int]:
    address, port = text.split(":")
    raw = bytes.fromhex(address)
    if proto.endswith("6"):
        # /proc writes IPv6 as four host-order 32-bit words
        raw = b"".join(raw[i : i + 4][::-1] for i in range(0, 16, 4))
        return socket.inet_ntop(socket.AF_INET6, raw), int(port, 16)
    return socket.inet_ntop(socket.AF_INET, raw[::-1]), int(port, 16)


def own_sockets() -> set[BoundSocket]:
    """TCP listening sockets and UDP sockets owned by this process (from /proc, no psutil)."""
    inodes = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[len("socket:[") : -1])
    found = set()
    for proto in ("tcp", "tcp6", "udp", "udp6"):
        table = Path(f"/proc/self/net/{proto}")
        if not table.exists():
            continue
        for line in table.read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] not in inodes or (proto.startswith("tcp") and fields[3] != TCP_LISTEN):
                continue
            address, port = _hex_address(fields[1], proto)
            found.add(BoundSocket(proto, address, port, fields[3]))
    return found
