"""A raw RTDE client that records when each 125 Hz data package arrives, to show the emulator's stream never stops.

It speaks the protocol as UR's own Python client does (``rtde/rtde.py``: REQUEST_PROTOCOL_VERSION 2, SETUP_OUTPUTS
with a frequency, START) and reads in a process of its own (forked), so that the test process's own work (hypothesis
building examples holds its interpreter for hundreds of ms) never shows as a gap; arrival times go to shared
memory. :meth:`RtdeWatcher.max_gap_s` is the longest time without a package over a window, on the system's monotonic
clock at arrival (the packages' own ``timestamp`` cannot show a stall: the emulator's loop catches its missed cycles
up afterwards, evenly stamped).
"""

from __future__ import annotations

import bisect
import itertools
import multiprocessing as mp
import socket
import struct
import time
from typing import Any

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.config import RTDE_PORT

CAPACITY = 125 * 900
"""Arrival times kept (15 minutes at 125 Hz); the watcher stops recording when they are full."""
ERRORS = {1: "the emulator closed the watcher's connection", 2: "the watcher's connection failed", 3: "buffer full"}


def rtde_request(sock: socket.socket, reader: rp.PackageReader, kind: int, payload: bytes = b"") -> bytes:
    """Send one request and return the payload of the first answer of the same type (``OSError`` if none)."""
    sock.sendall(rp.pack(kind, payload))
    while True:
        data = sock.recv(65536)
        if not data:
            raise OSError(f"RTDE connection closed before the answer to {chr(kind)!r}")
        for k, p in reader.feed(data):
            if k == kind:
                return p


def _watch(host: str, port: int, arrivals: Any, count: Any, status: Any, stop: Any) -> None:
    """The watcher process: set up, START, then write each data package's arrival time (s, monotonic)."""
    try:
        sock = socket.create_connection((host, port), timeout=2.0)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        reader = rp.PackageReader()
        assert rtde_request(sock, reader, rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        assert rtde_request(sock, reader, rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"timestamp") == b"\x01DOUBLE"
        assert rtde_request(sock, reader, rp.START) == b"\x01"
        sock.settimeout(0.2)
    except (OSError, AssertionError):
        status.value = 2
        return
    with sock:
        while not stop.is_set():
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                status.value = 2
                return
            if not data:
                status.value = 1
                return
            t = time.monotonic()
            for kind, _ in reader.feed(data):
                if kind != rp.DATA_PACKAGE:
                    continue
                if count.value >= CAPACITY:
                    status.value = 3
                    return
                arrivals[count.value] = t
                count.value += 1


class RtdeWatcher:
    """Receives ``timestamp`` at 125 Hz from an emulator, in a child process, and keeps every package's arrival time.

    Args:
        host: the emulator's address.
        port: its RTDE port.
    """

    def __init__(self, host: str, port: int = RTDE_PORT) -> None:
        self.host = host
        self.port = port
        ctx = mp.get_context("fork")
        self._arrivals = ctx.Array("d", CAPACITY, lock=False)
        self._count = ctx.Value("l", 0, lock=False)
        self._status = ctx.Value("i", 0, lock=False)
        self._stop = ctx.Event()
        self._proc = ctx.Process(
            target=_watch, args=(host, port, self._arrivals, self._count, self._status, self._stop), daemon=True
        )

    def start(self, timeout_s: float = 5.0) -> RtdeWatcher:
        """Start the watcher process and wait for its first package."""
        self._proc.start()
        deadline = time.monotonic() + timeout_s
        while not self._count.value and not self._status.value and time.monotonic() < deadline:
            time.sleep(0.005)
        assert self._count.value, f"no RTDE data package within {timeout_s} s ({self.error})"
        return self

    @property
    def error(self) -> str | None:
        """Why the watcher stopped receiving, or None while it receives."""
        return ERRORS.get(self._status.value)

    @property
    def arrivals(self) -> list[float]:
        """Every package's arrival time so far (s, monotonic), in order."""
        return list(self._arrivals[: self._count.value])

    def max_gap_s(self, t_from: float, t_to: float) -> float:
        """Longest time without a package between ``t_from`` and ``t_to`` (s, monotonic), both ends counted."""
        arrivals = self.arrivals
        i = bisect.bisect_right(arrivals, t_from)
        j = bisect.bisect_right(arrivals, t_to)
        points = [arrivals[i - 1] if i > 0 else t_from, *arrivals[i:j], t_to]
        return max(b - a for a, b in itertools.pairwise(points))

    def stop(self) -> None:
        """End the watcher process (it closes its connection)."""
        self._stop.set()
        self._proc.join(timeout=2.0)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(timeout=2.0)
