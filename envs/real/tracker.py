"""Optical-tracker adapters for the real cell: what the env needs from a tracker, and two sources.

The env asks a tracker for the newest marker position (m, UR base frame) and its age; registration of
the tracker's frame to the robot base is the adapter's job. Provided:

* :class:`NoTracker` — no tracker fitted (``tracker_valid`` stays 0).
* :class:`UdpTracker` — the marker stream of the drillgym UR emulator (a drillgym protocol, not NDI's):
  request ``b"DGTR" + uint8 1`` (start) / ``0`` (stop) to its UDP port; records are
  ``4s magic, uint32 seq, float64 t_s, float64 x, y, z (m, base frame), uint8 valid``, big-endian.

An NDI (Polaris / Vega) adapter implements the same :class:`Tracker` protocol.
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from drillgym.envs.errors import UserError

TRACKER_PORT = 49153
MAGIC = b"DGTR"
REQUEST = struct.Struct(">4sB")
RECORD = struct.Struct(">4sIddddB")


@dataclass(frozen=True)
class MarkerReading:
    """One marker position reading."""

    t_recv_s: float
    """Arrival time, ``time.monotonic()`` (s)."""
    position_base_m: np.ndarray
    """Marker position (m, UR base frame)."""


class Tracker(Protocol):
    """What the real env needs from a tracker."""

    fitted: bool
    """Whether a tracker is fitted at all (``False``: the observation's ``tracker_valid`` is always 0)."""

    def latest(self) -> MarkerReading | None:
        """The newest valid reading, or None."""
        ...

    def close(self) -> None:
        """Release the device."""
        ...


class NoTracker:
    """No tracker fitted."""

    fitted = False

    def latest(self) -> MarkerReading | None:
        """Always None."""
        return None

    def close(self) -> None:
        """Nothing to release."""


def pack_tracker_record(seq: int, t_s: float, position_base_m: np.ndarray, valid: bool) -> bytes:
    """One marker record of the emulator's tracker stream."""
    x, y, z = (float(v) for v in position_base_m)
    return RECORD.pack(MAGIC, seq & 0xFFFFFFFF, t_s, x, y, z, 1 if valid else 0)


def unpack_tracker_request(data: bytes) -> bool:
    """True for a start request, False for stop; ``ValueError`` if it is not a tracker request."""
    if len(data) != REQUEST.size:
        raise ValueError(f"tracker request must be {REQUEST.size} bytes, got {len(data)}")
    magic, start = REQUEST.unpack(data)
    if magic != MAGIC:
        raise ValueError(f"not a tracker request (magic {magic!r})")
    return bool(start)


class UdpTracker:
    """Receives the emulator's marker stream on a background thread."""

    fitted = True

    def __init__(self, host: str, port: int = TRACKER_PORT, recv_timeout_s: float = 0.05) -> None:
        self.address = (host, int(port))
        self._latest: MarkerReading | None = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(recv_timeout_s)
        self.sock.connect(self.address)
        self.sock.send(REQUEST.pack(MAGIC, 1))
        self._thread = threading.Thread(target=self._receive_loop, name="tracker-rx", daemon=True)
        self._thread.start()

    def _receive_loop(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.sock.recv(256)
            except TimeoutError:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                time.sleep(0.01)
                continue
            if len(data) != RECORD.size:
                continue
            magic, _seq, _t, x, y, z, valid = RECORD.unpack(data)
            if magic != MAGIC or not valid:
                continue
            reading = MarkerReading(time.monotonic(), np.array([x, y, z]))
            with self._lock:
                self._latest = reading

    def latest(self) -> MarkerReading | None:
        """The newest valid reading, or None."""
        with self._lock:
            return self._latest

    def close(self) -> None:
        """Stop the stream and the thread (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        try:
            self.sock.send(REQUEST.pack(MAGIC, 0))
        except OSError:
            pass
        self._thread.join(timeout=1.0)
        self.sock.close()


def make_tracker(spec: str | None) -> Tracker:
    """A tracker from a spec: ``None`` / ``"none"``, or ``"udp:HOST[:PORT]"`` (the emulator's stream)."""
    if spec is None or spec == "none":
        return NoTracker()
    kind, _, rest = spec.partition(":")
    if kind == "udp" and rest:
        host, _, port = rest.partition(":")
        return UdpTracker(host, int(port) if port else TRACKER_PORT)
    raise UserError(f"tracker={spec!r}: expected 'none' or 'udp:HOST[:PORT]'")
