"""The CB3's client-interface state streams on the script ports: 30001 / 30002 at 10 Hz, 30003 every cycle.

A CB3 sends every client of its primary (30001) and secondary (30002) interface a version message when it connects
and then a robot state message every 100 ms; every client of its real-time interface (30003) gets the real-time
packet every 8 ms controller cycle (UR's "Client Interface" documentation, CB3 3.x; the packet layouts are in
:mod:`~drillgym.envs.real.emulator.primary_state`). The same ports take URScript, and clients that only send
programs never read these streams: ``ur_rtde`` keeps one connection to 30003 open for the life of its control
interface and never reads it. So a client whose socket is full is not dropped: the packets it cannot take now are
skipped (a whole packet or none, so the stream stays framed), counted, and said once in the log; the connection,
and the programs it sends later, go on.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping

from drillgym.envs.real.emulator.nonblocking import StreamClient
from drillgym.envs.real.emulator.primary_state import realtime_packet, robot_state_message, version_message

STATE_PERIOD_S = 0.1
"""Robot state messages on 30001 / 30002: 10 Hz."""
STATE_KINDS = ("primary", "secondary")
REALTIME_KIND = "script"
"""The real-time interface (30003) is the emulator's ``script`` port."""


class StateStreams:
    """Sends the state streams to the script-port clients, one controller cycle at a time."""

    def __init__(self) -> None:
        self.next_state_s = 0.0
        self.skipped: dict[int, int] = {}
        """Packets skipped per client (``id`` of its :class:`StreamClient`) since it connected."""
        self.sent = {"state": 0, "realtime": 0}
        self.pack_errors = 0

    @staticmethod
    def greeting(t_s: float) -> bytes:
        """What a new 30001 / 30002 client gets first: the version message."""
        return version_message(t_s)

    def tick(self, t_s: float, state: Mapping[str, object], clients: Iterable[StreamClient]) -> None:
        """One controller cycle at emulator time ``t_s`` (s) with its controller ``state``."""
        realtime: bytes | None = None
        robot_state: bytes | None = None
        state_due = t_s >= self.next_state_s
        if state_due:
            self.next_state_s = max(self.next_state_s + STATE_PERIOD_S, t_s - STATE_PERIOD_S)
        alive = set()
        for client in clients:
            alive.add(id(client))
            if client.closing:
                continue
            try:
                if client.kind == REALTIME_KIND:
                    realtime = realtime or realtime_packet(state)
                    self._offer(client, realtime, "realtime")
                elif client.kind in STATE_KINDS and state_due:
                    robot_state = robot_state or robot_state_message(state)
                    self._offer(client, robot_state, "state")
            except (struct.error, ValueError, TypeError, KeyError, OverflowError) as e:  # a state it cannot pack
                self.pack_errors += 1
                client.log(f"state packet not packable ({type(e).__name__}: {e}); skipped")
        for gone in set(self.skipped) - alive:
            del self.skipped[gone]

    def _offer(self, client: StreamClient, packet: bytes, what: str) -> None:
        """Queue ``packet`` unless the client has not taken the previous one yet (then skip it)."""
        if client.outbox.pending:
            n = self.skipped.get(id(client), 0) + 1
            self.skipped[id(client)] = n
            if n == 1:
                client.log(f"does not read its {what} stream: packets are skipped while its socket is full")
            return
        client.outbox.queue(packet)
        self.sent[what] += 1
