"""ATI Net F/T over its RDT (Raw Data Transfer) UDP protocol: the wire format and a small client.

Protocol (ATI Net F/T manual 9620-05-NET FT, "UDP Interface Using RDT"), big-endian:

* request, 8 bytes: ``uint16 0x1234, uint16 command, uint32 sample_count`` (0 = stream until stopped).
  Commands: 0x0000 stop, 0x0002 start real-time streaming, 0x0042 set software bias.
* record, 36 bytes: ``uint32 rdt_sequence, uint32 ft_sequence, uint32 status, int32 Fx, Fy, Fz, Tx, Ty, Tz``
  in counts; force = counts / counts-per-force, torque = counts / counts-per-torque (the sensor's
  calibration, ``cfgcpf`` / ``cfgcpt`` on its ``netftapi2.xml`` page).

:class:`NetFTClient` asks for an endless stream, receives it on a thread and keeps the newest records with
their arrival time (``time.monotonic()``), converted to SI (N, N·m, sensor frame).
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.real.net_errors import connect_error

RDT_PORT = 49152
RDT_HEADER = 0x1234
CMD_STOP = 0x0000
CMD_START_REALTIME = 0x0002
CMD_SET_SOFTWARE_BIAS = 0x0042
REQUEST = struct.Struct(">HHI")
RECORD = struct.Struct(">III6i")


@dataclass(frozen=True)
class NetFTCalibration:
    """Counts per unit of the sensor's calibration (read from its web page, ``netftapi2.xml``)."""

    counts_per_force: float = 1_000_000.0
    """Counts per N (``cfgcpf`` with force units N)."""
    counts_per_torque: float = 1_000_000.0
    """Counts per N·m (``cfgcpt`` with torque units N·m)."""

    def __post_init__(self) -> None:
        if not (self.counts_per_force > 0 and self.counts_per_torque > 0):
            raise UserError(f"counts per force/torque must be > 0, got {self}")

    def to_si(self, counts: np.ndarray) -> np.ndarray:
        """(Fx, Fy, Fz, Tx, Ty, Tz) in N and N·m from counts."""
        c = np.asarray(counts, dtype=float)
        return np.concatenate([c[:3] / self.counts_per_force, c[3:] / self.counts_per_torque])

    def to_counts(self, wrench: np.ndarray) -> list[int]:
        """Counts (int32) of a wrench in N and N·m; saturates at the int32 range."""
        w = np.asarray(wrench, dtype=float)
        scaled = np.concatenate([w[:3] * self.counts_per_force, w[3:] * self.counts_per_torque])
        return [int(v) for v in np.clip(np.rint(scaled), -(2**31), 2**31 - 1)]


def pack_request(command: int, sample_count: int = 0) -> bytes:
    """An 8-byte RDT request."""
    return REQUEST.pack(RDT_HEADER, command, sample_count)


def unpack_request(data: bytes) -> tuple[int, int]:
    """``(command, sample_count)`` of a request; ``ValueError`` if it is not one."""
    if len(data) < REQUEST.size:
        raise ValueError(f"RDT request too short ({len(data)} bytes)")
    header, command, count = REQUEST.unpack_from(data)
    if header != RDT_HEADER:
        raise ValueError(f"not an RDT request (header 0x{header:04x})")
    return command, count


def pack_record(rdt_sequence: int, ft_sequence: int, status: int, counts: list[int]) -> bytes:
    """A 36-byte RDT record."""
    return RECORD.pack(rdt_sequence & 0xFFFFFFFF, ft_sequence & 0xFFFFFFFF, status, *counts)


@dataclass(frozen=True)
class FTRecord:
    """One received F/T record."""

    t_recv_s: float
    """Arrival time, ``time.monotonic()`` (s)."""
    rdt_sequence: int
    status: int
    wrench: np.ndarray
    """(Fx, Fy, Fz, Tx, Ty, Tz): N and N·m, sensor frame, not tared."""


class NetFTClient:
    """Streams an ATI Net F/T (RDT over UDP) on a background thread.

    Args:
        host: the sensor's address.
        port: its RDT port (49152).
        calibration: counts per force and torque.
        history_s: how much of the stream to keep (s).
        recv_timeout_s: socket timeout of the receive loop (bounds how long ``close`` waits).
        on_record: called with every record as it arrives (on the receive thread), e.g. to share it with another
            process (:class:`drillgym.envs.real.servo_shared.SharedFTRing`).
    """

    def __init__(
        self,
        host: str,
        port: int = RDT_PORT,
        calibration: NetFTCalibration | None = None,
        history_s: float = 5.0,
        recv_timeout_s: float = 0.05,
        on_record: Callable[[FTRecord], None] | None = None,
    ) -> None:
        self.address = (host, int(port))
        self.on_record = on_record
        self.calibration = calibration or NetFTCalibration()
        self._records: deque[FTRecord] = deque(maxlen=max(int(history_s * 8000), 100))
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.settimeout(recv_timeout_s)
        self.received = 0
        self.status_errors = 0
        self.malformed = 0
        self._thread = threading.Thread(target=self._receive_loop, name="netft-rx", daemon=True)
        try:
            self.sock.connect(self.address)
            self.sock.send(pack_request(CMD_START_REALTIME, 0))
        except OSError as e:
            self.sock.close()
            raise connect_error(e, host, int(port), "the F/T sensor's RDT stream (UDP)") from e
        self._thread.start()

    def _receive_loop(self) -> None:
        cal = self.calibration
        while not self._stop.is_set():
            try:
                data = self.sock.recv(2048)
            except TimeoutError:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                time.sleep(0.01)  # e.g. ICMP port unreachable while the sensor restarts
                continue
            t = time.monotonic()
            if len(data) != RECORD.size:
                self.malformed += 1
                continue
            rdt_seq, _ft_seq, status, *counts = RECORD.unpack(data)
            if status:
                self.status_errors += 1
            rec = FTRecord(t, rdt_seq, status, cal.to_si(np.array(counts, dtype=float)))
            with self._lock:
                self._records.append(rec)
                self.received += 1
            if self.on_record is not None:
                self.on_record(rec)

    def latest(self) -> FTRecord | None:
        """The newest record, or None before the first."""
        with self._lock:
            return self._records[-1] if self._records else None

    def since(self, t_start_s: float) -> list[FTRecord]:
        """Records that arrived at or after ``t_start_s`` (monotonic clock), oldest first."""
        with self._lock:
            out = []
            for rec in reversed(self._records):
                if rec.t_recv_s < t_start_s:
                    break
                out.append(rec)
        out.reverse()
        return out

    def bias(self) -> None:
        """Ask the sensor to zero itself (RDT software bias, command 0x0042)."""
        self.sock.send(pack_request(CMD_SET_SOFTWARE_BIAS, 0))

    def close(self) -> None:
        """Stop the stream and the thread (idempotent)."""
        if self._stop.is_set():
            return
        self._stop.set()
        try:
            self.sock.send(pack_request(CMD_STOP, 0))
        except OSError:
            pass
        self._thread.join(timeout=1.0)
        self.sock.close()
