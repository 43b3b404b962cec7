"""Bounded, non-blocking client I/O of the emulator: no client can stall its loop or grow its memory or log.

The emulator serves every port from one thread that also runs the 125 Hz controller, the physics and the F/T
stream, so a socket call that waits for a client stops all of them. Here every send is non-blocking into a
bounded :class:`Outbox` (a client that lets :attr:`Outbox.limit_bytes` pile up is dropped by its owner, and
logged), every read takes at most one chunk per loop turn (:data:`READ_CHUNK_BYTES`), a line client's commands
at most :data:`LINE_TURN_BUDGET_S` of each turn, and a client's complaints
and notes reach the log at most :data:`LINES_LOGGED` times (:class:`LogBudget`).
"""

from __future__ import annotations

import socket
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
LINES_LOGGED = 20
"""Lines about one client (protocol complaints, notes) written to the log; later ones are counted, not written."""


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
    """Writes lines about one client to the log until its budget is spent, then says once that it stops.

    Args:
        log: the emulator's log (one line per call).
        prefix: names the client in each line (e.g. ``rtde#3``).
        limit: lines written before the rest are only counted.
    """

    def __init__(self, log: Callable[[str], None], prefix: str, limit: int = LINES_LOGGED) -> None:
        self.log = log
        self.prefix = prefix
        self.limit = limit
        self.count = 0

    def __call__(self, line: str) -> None:
        """Log one line about the client (counted always, written while the budget lasts)."""
        self.count += 1
        if self.count <= self.limit:
            self.log(f"{self.prefix}: {line}")
        if self.count == self.limit:
            self.log(f"{self.prefix}: {self.limit} lines logged about this client; further ones are not")


@dataclass
class StreamClient:
    """One client of a line or script port (dashboard, control, script ports, F/T calibration).

    Attributes:
        kind: the port's name (``dashboard``, ``control``, ``script``, ``primary``, ``secondary``, ``ft_cal``).
        inbox: received bytes not yet handled.
        outbox: replies not yet sent.
        log: lines about the client, within its budget.
        closing: close once the outbox is empty (a ``quit``, a ``shutdown``, a one-shot reply).
    """

    kind: str
    inbox: bytearray
    outbox: Outbox
    log: LogBudget
    closing: bool = False
