"""A raw RTDE client that records when each 125 Hz data package arrives, to show the emulator's stream never stops.

It speaks the protocol as UR's own Python client does (``rtde/rtde.py``: REQUEST_PROTOCOL_VERSION 2, SETUP_OUTPUTS
with a frequency, START) and reads in a thread of its own; :meth:`RtdeWatcher.max_gap_s` is the longest time
without a package over a window, measured on this process's monotonic clock at arrival (the packages' own
``timestamp`` cannot show a stall: the emulator's loop catches its missed cycles up afterwards, evenly stamped).
"""

from __future__ import annotations

import bisect
import itertools
import socket
import struct
import threading
import time

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.config import RTDE_PORT


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


class RtdeWatcher:
    """Receives ``timestamp`` at 125 Hz from an emulator and keeps every package's arrival time (s, monotonic).

    Args:
        host: the emulator's address.
        port: its RTDE port.
    """

    def __init__(self, host: str, port: int = RTDE_PORT) -> None:
        self.host = host
        self.port = port
        self.arrivals: list[float] = []
        self.error: str | None = None
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

    def start(self, timeout_s: float = 2.0) -> RtdeWatcher:
        """Connect, set the recipe up, START, and wait for the first package."""
        sock = socket.create_connection((self.host, self.port), timeout=timeout_s)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        reader = rp.PackageReader()
        assert rtde_request(sock, reader, rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        answer = rtde_request(sock, reader, rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"timestamp")
        assert answer == b"\x01DOUBLE", answer
        assert rtde_request(sock, reader, rp.START) == b"\x01"
        sock.settimeout(0.2)
        self._sock = sock
        self._thread = threading.Thread(target=self._run, args=(sock, reader), daemon=True)
        self._thread.start()
        deadline = time.monotonic() + timeout_s
        while not self.arrivals and time.monotonic() < deadline:
            time.sleep(0.005)
        assert self.arrivals, f"no RTDE data package within {timeout_s} s"
        return self

    def _run(self, sock: socket.socket, reader: rp.PackageReader) -> None:
        while not self._stop.is_set():
            try:
                data = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as e:
                self.error = f"watcher connection failed: {e}"
                return
            if not data:
                self.error = "the emulator closed the watcher's connection"
                return
            t = time.monotonic()
            n = sum(1 for kind, _ in reader.feed(data) if kind == rp.DATA_PACKAGE)
            self.arrivals.extend([t] * n)

    def max_gap_s(self, t_from: float, t_to: float) -> float:
        """Longest time without a package between ``t_from`` and ``t_to`` (s, monotonic), both ends counted."""
        arrivals = list(self.arrivals)
        i = bisect.bisect_right(arrivals, t_from)
        j = bisect.bisect_right(arrivals, t_to)
        points = [arrivals[i - 1] if i > 0 else t_from, *arrivals[i:j], t_to]
        return max(b - a for a, b in itertools.pairwise(points))

    def stop(self) -> None:
        """End the thread and close the connection."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
        if self._sock is not None:
            self._sock.close()
