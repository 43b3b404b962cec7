"""The emulated cell's UDP sensor streams: the ATI Net F/T (RDT) and the marker stream.

One client each (the Net F/T serves one client); a start request from a new address takes the stream over.
"""

from __future__ import annotations

import math
import socket
from collections.abc import Callable

from drillgym.envs.real import netft, tracker
from drillgym.envs.real.emulator.config import EmulatorConfig
from drillgym.envs.real.emulator.faults import FaultState
from drillgym.envs.real.emulator.world import EmulatedCell


class SensorStreams:
    """F/T and marker streams driven by the emulator loop."""

    def __init__(
        self,
        world: EmulatedCell,
        config: EmulatorConfig,
        bind_udp: Callable[[int, Callable[[socket.socket], None]], socket.socket],
    ) -> None:
        self.world = world
        self.config = config
        self.bind_udp = bind_udp
        self.ft_sock: socket.socket | None = None
        self.trk_sock: socket.socket | None = None
        self.ft_client: tuple[str, int] | None = None
        self.ft_remaining = 0
        """Records still to send for a counted request; -1 streams until stopped."""
        self.rdt_sequence = 0
        self.ft_sequence = 0
        self.ft_sent = 0
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

    def next_due_s(self) -> float:
        """When the loop must wake up next for a record (s, emulator time)."""
        due = math.inf
        if self.ft_client is not None and self.ft_remaining != 0:
            due = self.next_ft_s
        if self.trk_client is not None:
            due = min(due, self.next_trk_s)
        return due

    def _ft_request(self, sock: socket.socket) -> None:
        try:
            data, addr = sock.recvfrom(64)
            command, count = netft.unpack_request(data)
        except (OSError, ValueError):
            self.bad_requests += 1
            return
        if command == netft.CMD_START_REALTIME:
            self.ft_client = addr
            self.ft_remaining = count if count > 0 else -1
            self.rdt_sequence = 0
        elif command == netft.CMD_STOP:
            self.ft_remaining = 0
        elif command == netft.CMD_SET_SOFTWARE_BIAS:
            self.world.bias_ft()
        else:
            self.bad_requests += 1

    def _trk_request(self, sock: socket.socket) -> None:
        try:
            data, addr = sock.recvfrom(64)
            start = tracker.unpack_tracker_request(data)
        except (OSError, ValueError):
            self.bad_requests += 1
            return
        self.trk_client = addr if start else None

    def tick(self, now_s: float, faults: FaultState) -> None:
        """Send the records that are due."""
        if self.ft_client is not None and self.ft_remaining != 0 and now_s >= self.next_ft_s:
            self.next_ft_s = max(self.next_ft_s + self.ft_period_s, now_s - 0.1)
            self.ft_sequence += 1
            if not faults.stale_ft and self.ft_sock is not None:
                self.rdt_sequence += 1
                counts = self.config.calibration.to_counts(self.world.ft_reading())
                record = netft.pack_record(self.rdt_sequence, self.ft_sequence, 0, counts)
                try:
                    self.ft_sock.sendto(record, self.ft_client)
                    self.ft_sent += 1
                except OSError:
                    pass
                if self.ft_remaining > 0:
                    self.ft_remaining -= 1
        if self.trk_client is not None and now_s >= self.next_trk_s:
            self.next_trk_s = max(self.next_trk_s + self.trk_period_s, now_s - 0.1)
            if not faults.stale_tracker and self.trk_sock is not None:
                self.trk_sequence += 1
                record = tracker.pack_tracker_record(self.trk_sequence, now_s, self.world.marker_reading(), True)
                try:
                    self.trk_sock.sendto(record, self.trk_client)
                except OSError:
                    pass
