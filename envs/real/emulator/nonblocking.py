"""Bounded, non-blocking client I/O of the emulator: no client can stall its loop or grow its memory or log.

The emulator serves every port from one thread that also runs the 125 Hz controller, the physics and the F/T
stream, so a socket call that waits for a client stops all of them. Here every send is non-blocking into a
bounded :class:`Outbox` (a client that lets :attr:`Outbox.limit_bytes` pile up is dropped by its owner, and
logged), every read takes at most one chunk per loop turn (:data:`READ_CHUNK_BYTES`), a line client's commands
at most :data:`LINE_TURN_BUDGET_S` of each turn, and the lines about one port's clients reach the log at most in
bursts of :data:`LOG_BURST_LINES` and :data:`LOG_LINES_PER_S` lines a second after (:class:`LogBudget`).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from dataclasses import dataclass

READ_CHUNK_BYTES = {"rtde": 16384, "dashboard": 4096, "control": 4096, "ft_cal": 4096, "ft_http": 4096}
"""Bytes read from one client per loop turn (the rest waits in the kernel for the next turn), by port kind; the
script ports read :data:`SCRIPT_CHUNK_BYTES`. 16 KiB of RTDE is several seconds of ``ur_rtde``'s input packages
and 4 KiB at most 2048 dashboard commands, a few milliseconds of work."""
SCRIPT_CHUNK_BYTES = 65536
LINE_TURN_BUDGET_S = 0.002
"""Time one dashboard or control client's commands may take per loop turn (s); lines left over wait for the next
turns (a control port ``status`` takes about 0.1 ms, so 4 KiB of them would otherwise hold the loop ~20 ms)."""
STREAM_OUTBOX_BYTES = 65536
"""Unsent replies a dashboard, control or calibration client may let pile up before it is dropped (bytes)."""
MAX_LINE_BYTES = 4096
"""Longest dashboard or control line accepted without a newline (bytes); a longer one drops the client."""
MAX_SCRIPT_BYTES = 1 << 20
"""Longest incomplete program a script port buffers (bytes); more drops the client."""
LOG_BURST_LINES = 20
"""Lines about one port's clients (protocol complaints, notes) the log takes at once (:class:`LogBudget`)."""
LOG_LINES_PER_S = 1.0
"""The rate (lines/s) at which that allowance comes back: a client that reconnects in a loop cannot flood the log."""


class Outbox:
    """Bytes waiting to leave on a non-blocking socket.

    Args:
        sock: the client's socket (non-blocking).
        limit_bytes: the backlog (bytes) at which :meth:`flush` reports the client as too slow.
    """

    def __init__(self, sock: socket.socket, limit_bytes: int) -> None:
        self.sock = sock
        self.limit_bytes = limit_bytes
        self.pending = bytearray()

    def queue(self, data: bytes) -> None:
        """Append bytes to send (the caller flushes)."""
        self.pending.extend(data)

    def flush(self) -> bool:
        """Send what the socket takes now, never waiting; False if the peer is gone or the backlog is at the limit."""
        if self.pending:
            try:
                n = self.sock.send(self.pending)
            except (BlockingIOError, InterruptedError):
                n = 0
            except OSError:
                return False
            del self.pending[:n]
        return len(self.pending) < self.limit_bytes


class LogBudget:
    """A token bucket for the lines about one port's clients: a burst, then a steady rate.

    What it holds back is counted, and said with the next line it lets through.

    Args:
        log: the emulator's log (one line per call).
        prefix: put before each line with ``": "`` (e.g. ``ft rdt``); none if empty.
        burst: lines let through at once.
        per_s: lines per second the allowance comes back at.
        clock: seconds, monotonic.
    """

    def __init__(
        self,
        log: Callable[[str], None],
        prefix: str = "",
        burst: int = LOG_BURST_LINES,
        per_s: float = LOG_LINES_PER_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.log = log
        self.prefix = f"{prefix}: " if prefix else ""
        self.burst = burst
        self.per_s = per_s
        self.clock = clock
        self.tokens = float(burst)
        self.last_s = clock()
        self.held_back = 0

    def __call__(self, line: str) -> None:
        """Log one line if the allowance has room, else count it."""
        now = self.clock()
        self.tokens = min(float(self.burst), self.tokens + (now - self.last_s) * self.per_s)
        self.last_s = now
        if self.tokens < 1.0:
            self.held_back += 1
            return
        self.tokens -= 1.0
        if self.held_back:
            line += f" ({self.held_back} earlier line(s) about this port's clients not logged)"
            self.held_back = 0
        self.log(self.prefix + line)


@dataclass
class StreamClient:
    """One client of a line or script port (dashboard, control, script ports, F/T calibration).

    Attributes:
        kind: the port's name (``dashboard``, ``control``, ``script``, ``primary``, ``secondary``, ``ft_cal``).
        inbox: received bytes not yet handled.
        outbox: replies not yet sent.
        log: lines about the client (with its port's :class:`LogBudget`).
        closing: close once the outbox is empty (a ``quit``, a ``shutdown``, a one-shot reply).
    """

    kind: str
    inbox: bytearray
    outbox: Outbox
    log: Callable[[str], None]
    closing: bool = False
