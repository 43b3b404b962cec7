"""What the agent and the servo loop share: the commanded correction, and the F/T records.

Both come in two forms with one interface: in one process (a lock), and across processes (``multiprocessing``
shared memory, created by the agent's process and handed to the servo process when it starts), so
:class:`drillgym.envs.real.servo.ServoLoop` runs unchanged in either.

* :class:`CommandSlot` / :class:`SharedCommandSlot`: correction (m, base frame), feed override, and when the agent
  commanded it (``time.monotonic()``, s; the clock is system-wide on Linux, so both processes compare it).
* :class:`SharedFTRing`: the F/T records the servo process receives, written by it, read by the agent's
  process (arrival time, ``time.monotonic()``; wrench in N and N·m, sensor frame, not tared).
"""

from __future__ import annotations

import multiprocessing
import threading
import time
from typing import Any

import numpy as np

from drillgym.envs.real import safety
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.netft import FTRecord

_SLOT_SIZE = 5
"""Correction (3), feed override, command time."""


class CommandSlot:
    """The latest command, within one process."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._values = np.zeros(_SLOT_SIZE)

    def write(self, correction_base_m: np.ndarray, feed_scale: float, t_s: float) -> None:
        """Store a command (m, base frame; feed override; ``time.monotonic()`` of the command, s)."""
        with self._lock:
            self._values[:3] = correction_base_m
            self._values[3] = feed_scale
            self._values[4] = t_s

    def read(self) -> tuple[np.ndarray, float, float]:
        """``(correction_base_m, feed_scale, t_s)`` of the latest command."""
        with self._lock:
            v = self._values.copy()
        return v[:3], float(v[3]), float(v[4])


class SharedCommandSlot(CommandSlot):
    """The latest command in shared memory (give it to the other process when starting it).

    Lock-free (a sequence lock, one writer: the agent): the writer makes the sequence number odd, writes, makes
    it even again; a reader copies between two reads of an even, unchanged number. No reader ever waits for the
    writer: a lock would let the ordinary-priority agent process, preempted while holding it, stall the
    real-time servo loop (priority inversion). A reader that keeps meeting a write in progress keeps the
    command it read before (one cycle late at worst).
    """

    READ_ATTEMPTS = 100

    def __init__(self, context: Any = None) -> None:
        ctx = context or multiprocessing.get_context("spawn")
        self._array = ctx.RawArray("d", 1 + _SLOT_SIZE)
        self._last = (np.zeros(3), 1.0, 0.0)

    def write(self, correction_base_m: np.ndarray, feed_scale: float, t_s: float) -> None:
        """Store a command (see :meth:`CommandSlot.write`); one writer only."""
        corr = np.asarray(correction_base_m, dtype=float)
        a = self._array
        a[0] += 1.0  # odd: writing
        a[1:] = [float(corr[0]), float(corr[1]), float(corr[2]), float(feed_scale), float(t_s)]
        a[0] += 1.0  # even: done

    def read(self) -> tuple[np.ndarray, float, float]:
        """``(correction_base_m, feed_scale, t_s)`` of the latest command."""
        a = self._array
        for _ in range(self.READ_ATTEMPTS):
            seq = a[0]
            if seq % 2.0 == 0.0:
                v = a[1:]
                if a[0] == seq:
                    self._last = (np.array(v[:3]), v[3], v[4])
                    break
        corr, scale, t = self._last
        return corr.copy(), scale, t


_RECORD_FIELDS = 9
"""Arrival time, RDT sequence, status, wrench (6)."""


class SharedFTRing:
    """F/T records in a shared ring buffer: one writer (the servo process), readers in the agent's process.

    The writer fills a slot, then advances the count (an aligned 64-bit store); a reader copies the slots it
    wants, then drops any the writer may have overwritten meanwhile (the count read again), so a record is
    either whole or not returned. ``capacity`` records are kept (8000 per second of history at 8 kHz).
    """

    def __init__(self, capacity: int = 40_000, context: Any = None) -> None:
        if capacity < 100:
            raise ValueError(f"capacity={capacity} must be >= 100 records")
        ctx = context or multiprocessing.get_context("spawn")
        self.capacity = int(capacity)
        self._data = ctx.RawArray("d", self.capacity * _RECORD_FIELDS)
        self._count = ctx.RawValue("q", 0)

    # ------------------------------------------------------------------ writer
    def append(self, record: FTRecord) -> None:
        """Add one record (the servo process's F/T thread only)."""
        n = self._count.value
        i = (n % self.capacity) * _RECORD_FIELDS
        w = record.wrench
        self._data[i : i + _RECORD_FIELDS] = [
            record.t_recv_s,
            float(record.rdt_sequence),
            float(record.status),
            float(w[0]),
            float(w[1]),
            float(w[2]),
            float(w[3]),
            float(w[4]),
            float(w[5]),
        ]
        self._count.value = n + 1

    # ------------------------------------------------------------------ readers
    @property
    def count(self) -> int:
        """Records written so far."""
        return int(self._count.value)

    def _rows(self, first: int, end: int) -> np.ndarray:
        """Records ``first`` .. ``end - 1`` (absolute numbers) as rows, oldest first."""
        view = np.frombuffer(self._data, dtype=np.float64).reshape(self.capacity, _RECORD_FIELDS)
        idx = np.arange(first, end) % self.capacity
        return view[idx].copy()

    def latest(self) -> FTRecord | None:
        """The newest record, or None before the first."""
        n = self.count
        if n == 0:
            return None
        return _record(self._rows(n - 1, n)[0])

    def since(self, t_start_s: float) -> list[FTRecord]:
        """Records that arrived at or after ``t_start_s`` (monotonic clock), oldest first."""
        end = self.count
        view = np.frombuffer(self._data, dtype=np.float64).reshape(self.capacity, _RECORD_FIELDS)
        lo, hi = max(end - self.capacity + 1, 0), end  # binary search: arrival times grow with the count
        while lo < hi:
            mid = (lo + hi) // 2
            if view[mid % self.capacity, 0] < t_start_s:
                lo = mid + 1
            else:
                hi = mid
        rows = self._rows(lo, end)
        keep_from = max(self.count - self.capacity + 1, lo)  # slots the writer reused while we copied
        rows = rows[keep_from - lo :]
        return [_record(r) for r in rows if r[0] >= t_start_s]


def _record(row: np.ndarray) -> FTRecord:
    return FTRecord(float(row[0]), int(row[1]), int(row[2]), np.array(row[3:9]))


class HeldCommand:
    """The agent's side of the command slot, for the servo loop and its stand-in in the agent's process.

    ``command`` clips and writes the correction (m, base frame) and feed override, held until the next call;
    ``current_command`` reads what is being streamed. Needs ``slot`` and ``limits``.
    """

    slot: CommandSlot
    limits: SafetyLimits

    def command(self, correction_base_m: np.ndarray, feed_scale: float) -> None:
        """New correction (m, base frame; clipped) and feed override, held until the next call."""
        corr = safety.clip_correction(correction_base_m, self.limits)
        self.slot.write(corr, float(feed_scale), time.monotonic())

    def current_command(self) -> tuple[np.ndarray, float]:
        """The correction and feed override being streamed."""
        corr, scale, _ = self.slot.read()
        return corr, scale
