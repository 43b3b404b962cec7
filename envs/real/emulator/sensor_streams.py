"""The emulated cell's UDP sensor streams: the ATI Net F/T (RDT) and the marker stream.

One client each (the Net F/T serves one client); a start request from a new address takes the stream over.

The Net F/T follows ATI's manual 9620-05-NET FT, "UDP Interface Using RDT". A request is
``uint16 0x1234, uint16 command, uint32 sample_count`` (0: until stopped); the commands:

* ``0x0002`` start real-time streaming: one 36-byte record per UDP packet;
* ``0x0003`` start buffered streaming: the same records, :attr:`EmulatorConfig.ft_rdt_buffer_size` to a packet
  (the "RDT buffer size" of the sensor's Communication page, ``comrdtbsiz``), a packet whenever that many are due;
  ``sample_count`` counts records here too, so the last packet of a counted request may be short;
* ``0x0000`` stop; ``0x0042`` set software bias; ``0x0041`` reset threshold latch (accepted: no thresholds are
  emulated, so the latch is never set); anything else (``0x0004`` multi-unit streaming, not an RDT request) is
  counted and logged.

Sequences: ``rdt_sequence`` numbers the records of one stream, 1 for the first record after a start request, +1 per
record; it never moves while no stream runs. ``ft_sequence`` is the sensor's internal sample counter at the record's
time, running at :data:`INTERNAL_RATE_HZ` from power-up whether or not anything streams.

Pacing: records leave on a fixed grid at ``ft_rate_hz`` that a start request anchors at the moment it is served, so
a restart sends its first record at once and the next ones one period apart: no record leaves before its time on the
grid, and a restart flushes no backlog. A record the emulator's loop could not send within :data:`MAX_LAG_S` of its
time is lost, as on a congested link: its ``rdt_sequence`` is skipped (a client sees the gap) and it is counted in
:attr:`SensorStreams.ft_lost`.
"""

from __future__ import annotations

import math
import socket
from collections.abc import Callable

from drillgym.envs.real import netft, tracker
from drillgym.envs.real.emulator.config import EmulatorConfig
from drillgym.envs.real.emulator.faults import FaultState
from drillgym.envs.real.emulator.world import EmulatedCell

CMD_START_BUFFERED = 0x0003
CMD_RESET_THRESHOLD_LATCH = 0x0041
INTERNAL_RATE_HZ = 7000.0
"""The Net F/T's internal sample rate (Hz): what ``ft_sequence`` counts (``runrate`` on its web page)."""
MAX_LAG_S = 0.05
"""A record not sent within this long of its time is lost (s): after a stall of the emulator's loop (a loaded machine
holds it for tens of ms) at most 50 ms of records leave back to back, and never a record before its time."""
NOTES_LOGGED = 20
"""Lines about requests the Net F/T does not understand written to the log; later ones are only counted (the control
port's ``status``: ``ft_bad_requests``), so a datagram flood cannot flood the log."""


class SensorStreams:
    """F/T and marker streams driven by the emulator loop.

    Args:
        world: the emulated cell (F/T readings, marker positions).
        config: rates, ports, the calibration and the RDT buffer size.
        bind_udp: binds a UDP port and registers its reader with the loop.
        log: the emulator's log; the first :data:`NOTES_LOGGED` requests it does not understand are logged there.
    """

    def __init__(
        self,
        world: EmulatedCell,
        config: EmulatorConfig,
        bind_udp: Callable[[int, Callable[[socket.socket], None]], socket.socket],
        log: Callable[[str], None] | None = None,
    ) -> None:
        self.world = world
        self.config = config
        self.bind_udp = bind_udp
        self.log = log or (lambda _line: None)
        self.ft_sock: socket.socket | None = None
        self.trk_sock: socket.socket | None = None
        self.ft_client: tuple[str, int] | None = None
        self.ft_remaining = 0
        """Records still to send for a counted request; -1 streams until stopped."""
        self.ft_buffered = False
        """Buffered streaming (``0x0003``): records go out ``ft_rdt_buffer_size`` to a packet."""
        self._ft_batch: list[bytes] = []
        self._ft_anchor = False
        """A start request was received: the next tick starts the record grid at its own time."""
        self.rdt_sequence = 0
        self.ft_sent = 0
        """Records sent."""
        self.ft_lost = 0
        """Records lost because the loop came too late for them (their ``rdt_sequence`` is skipped)."""
        self.trk_client: tuple[str, int] | None = None
        self.trk_sequence = 0
        self.ft_period_s = 1.0 / config.ft_rate_hz
        self.trk_period_s = 1.0 / config.tracker_rate_hz
        self.next_ft_s = 0.0
        self.next_trk_s = 0.0
        self.bad_requests = 0

    def open(self) -> None:
        """Bind both UDP ports."""
        self.ft_sock = self.bind_udp(self.config.ft_port, self._ft_request)
        self.trk_sock = self.bind_udp(self.config.tracker_port, self._trk_request)

    def close(self) -> None:
        """Close both sockets."""
        for s in (self.ft_sock, self.trk_sock):
            if s is not None:
                s.close()

    @property
    def ft_streaming(self) -> bool:
        """Whether an RDT stream runs (started and not stopped or finished)."""
        return self.ft_client is not None and self.ft_remaining != 0

    def next_due_s(self) -> float:
        """When the loop must wake up next for a record (s, emulator time; 0: at once)."""
        due = math.inf
        if self.ft_streaming:
            due = 0.0 if self._ft_anchor else self.next_ft_s
        if self.trk_client is not None:
            due = min(due, self.next_trk_s)
        return due

    # ------------------------------------------------------------------ requests
    def _ft_request(self, sock: socket.socket) -> None:
        try:
            data, addr = sock.recvfrom(64)
        except OSError:
            return
        try:
            command, count = netft.unpack_request(data)
        except ValueError as e:
            self._bad_request(f"{len(data)}-byte datagram from {addr[0]}:{addr[1]} is not an RDT request ({e})")
            return
        if command in (netft.CMD_START_REALTIME, CMD_START_BUFFERED):
            self.ft_client = addr
            self.ft_remaining = count if count > 0 else -1
            self.ft_buffered = command == CMD_START_BUFFERED
            self._ft_batch.clear()
            self._ft_anchor = True
            self.rdt_sequence = 0
        elif command == netft.CMD_STOP:
            self.ft_remaining = 0
            self._ft_batch.clear()
        elif command == netft.CMD_SET_SOFTWARE_BIAS:
            self.world.bias_ft()
        elif command == CMD_RESET_THRESHOLD_LATCH:
            pass  # no thresholds are emulated: the latch is never set
        else:
            self._bad_request(f"RDT command 0x{command:04x} from {addr[0]}:{addr[1]} not emulated")

    def _bad_request(self, what: str) -> None:
        self.bad_requests += 1
        if self.bad_requests <= NOTES_LOGGED:
            self.log(f"ft rdt: {what}; ignored")
        if self.bad_requests == NOTES_LOGGED:
            self.log(f"ft rdt: {NOTES_LOGGED} requests not understood; further ones are only counted")

    def _trk_request(self, sock: socket.socket) -> None:
        try:
            data, addr = sock.recvfrom(64)
            start = tracker.unpack_tracker_request(data)
        except (OSError, ValueError):
            self.bad_requests += 1
            return
        self.trk_client = addr if start else None

    # ------------------------------------------------------------------ records
    def tick(self, now_s: float, faults: FaultState) -> None:
        """Send the records that are due."""
        if self.ft_streaming:
            self._tick_ft(now_s, faults)
        if self.trk_client is not None and now_s >= self.next_trk_s:
            self.next_trk_s = max(self.next_trk_s + self.trk_period_s, now_s - 0.1)
            if not faults.stale_tracker and self.trk_sock is not None:
                self.trk_sequence += 1
                record = tracker.pack_tracker_record(self.trk_sequence, now_s, self.world.marker_reading(), True)
                try:
                    self.trk_sock.sendto(record, self.trk_client)
                except OSError:
                    pass

    def _tick_ft(self, now_s: float, faults: FaultState) -> None:
        if self._ft_anchor:
            self._ft_anchor = False
            self.next_ft_s = now_s
        if now_s < self.next_ft_s:
            return
        period = self.ft_period_s
        due = int((now_s - self.next_ft_s) / period) + 1
        in_time = int(MAX_LAG_S / period) + 1
        if due > in_time:  # the loop was held up: the oldest records are lost
            lost = due - in_time
            if self.ft_remaining > 0:
                lost = min(lost, self.ft_remaining)
                self.ft_remaining -= lost
            self.rdt_sequence += lost
            self.ft_lost += lost
            self.next_ft_s += lost * period
            due -= lost
        while due > 0 and self.ft_remaining != 0:
            self._ft_record(self.next_ft_s, stale=faults.stale_ft)
            self.next_ft_s += period
            due -= 1

    def _ft_record(self, t_s: float, stale: bool) -> None:
        """One record at emulator time ``t_s`` (s); a stale sensor sends nothing (its stream stays on)."""
        if stale or self.ft_sock is None or self.ft_client is None:
            return
        self.rdt_sequence += 1
        counts = self.config.calibration.to_counts(self.world.ft_reading())
        ft_sequence = int(t_s * INTERNAL_RATE_HZ)
        record = netft.pack_record(self.rdt_sequence, ft_sequence, 0, counts)
        if self.ft_remaining > 0:
            self.ft_remaining -= 1
        if not self.ft_buffered:
            self._ft_send(record, 1)
            return
        self._ft_batch.append(record)
        if len(self._ft_batch) >= self.config.ft_rdt_buffer_size or self.ft_remaining == 0:
            self._ft_send(b"".join(self._ft_batch), len(self._ft_batch))
            self._ft_batch.clear()

    def _ft_send(self, packet: bytes, records: int) -> None:
        assert self.ft_sock is not None and self.ft_client is not None
        try:
            self.ft_sock.sendto(packet, self.ft_client)
            self.ft_sent += records
        except OSError:  # a full socket buffer or an unreachable client: the records are lost, the loop goes on
            pass
