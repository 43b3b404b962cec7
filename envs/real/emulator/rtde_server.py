"""One RTDE client connection (TCP 30004) of the emulated controller: setup, recipes, streaming, inputs.

Input recipes are numbered 1, 2, 3, ... per connection in setup order (``ur_rtde`` hard-codes those ids);
an input register another live connection already owns is answered ``IN_USE``; an unknown name
``NOT_FOUND``. Data packages are streamed at the requested frequency (at most the CB3's 125 Hz) from the
controller cycle; input data packages are accepted before START as well (``RTDEIOInterface`` never starts).
"""

from __future__ import annotations

import socket
import struct
from collections import deque
from collections.abc import Callable

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.registers import Registers

CONTROLLER_VERSION = (3, 15, 7, 106331)
"""PolyScope 3.15.7 (CB3): what ``GET_URCONTROL_VERSION`` answers; it selects ur_rtde's recipes and rates."""
CB3_RATE_HZ = 125.0
MAX_BACKLOG_BYTES = 1 << 20
"""A client that lets this much output pile up is disconnected (a real controller drops slow readers)."""


def output_divider(frequency_hz: float) -> int:
    """Controller cycles between output packages for a requested frequency (Hz).

    The frequency is clipped to the CB3's 1-125 Hz (UR's client library refuses more than 125 Hz on a CB3 before
    asking) and served at 125 Hz divided by the nearest whole number.
    """
    rate = min(max(frequency_hz, 1.0), CB3_RATE_HZ)
    return max(round(CB3_RATE_HZ / rate), 1)


class RtdeConnection:
    """Protocol state of one RTDE client.

    Args:
        sock: the accepted socket (non-blocking).
        registers: the controller's register file.
        owners: input field name -> owning connection id (shared by all connections).
        conn_id: this connection's id.
        log: called with one line per notable event.
        on_input: called after every input data package (with the emulator time).
    """

    def __init__(
        self,
        sock: socket.socket,
        registers: Registers,
        owners: dict[str, int],
        conn_id: int,
        log: Callable[[str], None],
        on_input: Callable[[float], None] = lambda t_s: None,
    ) -> None:
        self.sock = sock
        self.regs = registers
        self.owners = owners
        self.conn_id = conn_id
        self.log = log
        self.on_input = on_input
        self.reader = rp.PackageReader()
        self.output_names: list[str] = []
        self.output_types: list[str] = []
        self.output_struct: struct.Struct | None = None
        self.divider = 1
        self.started = False
        self.inputs: dict[int, tuple[list[str], list[str], struct.Struct]] = {}
        self.outbox = bytearray()
        self.delayed: deque[tuple[float, bytes]] = deque()
        self.sent_packages = 0
        self.input_recipe_log: list[list[str]] = []
        self.closed = False

    # ------------------------------------------------------------------ inbound
    def receive(self, data: bytes, t_s: float) -> None:
        """Handle received bytes (any number of packages)."""
        for kind, payload in self.reader.feed(data):
            self._handle(kind, payload, t_s)

    def _handle(self, kind: int, payload: bytes, t_s: float) -> None:
        if kind == rp.REQUEST_PROTOCOL_VERSION:
            version = struct.unpack_from(">H", payload)[0] if len(payload) >= 2 else 0
            self.send(rp.pack(kind, bytes([1 if version in (1, 2) else 0])))
        elif kind == rp.GET_URCONTROL_VERSION:
            self.send(rp.pack(kind, struct.pack(">IIII", *CONTROLLER_VERSION)))
        elif kind == rp.SETUP_OUTPUTS:
            self._setup_outputs(payload)
        elif kind == rp.SETUP_INPUTS:
            self._setup_inputs(payload)
        elif kind == rp.START:
            self.started = self.output_struct is not None
            self.send(rp.pack(kind, bytes([1 if self.started else 0])))
        elif kind == rp.PAUSE:
            self.started = False
            self.send(rp.pack(kind, bytes([1])))
        elif kind == rp.DATA_PACKAGE:
            self._input_package(payload, t_s)
        elif kind != rp.TEXT_MESSAGE:
            self.log(f"rtde#{self.conn_id}: unknown package type {kind}")

    def _setup_outputs(self, payload: bytes) -> None:
        frequency = struct.unpack_from(">d", payload)[0]
        names = [n for n in payload[8:].decode().split(",") if n]
        types = [rp.OUTPUT_TYPES.get(n, rp.NOT_FOUND) for n in names]
        if rp.NOT_FOUND not in types and names:
            self.output_names, self.output_types = names, types
            self.output_struct = rp.recipe_struct(types)
            self.divider = output_divider(frequency)
            served_hz = CB3_RATE_HZ / self.divider
            if abs(served_hz - frequency) > 1e-9:
                self.log(
                    f"rtde#{self.conn_id}: {frequency:g} Hz requested, served every {self.divider} controller cycle(s) "
                    f"({served_hz:.4g} Hz; a CB3's answer to this frequency is not documented, this rounding is the "
                    "emulator's)"
                )
            recipe_id = 1
            constant = [n for n in names if n in rp.NOT_EMULATED]
            if constant:
                self.log(f"rtde#{self.conn_id}: outputs not emulated (served as constants): {', '.join(constant)}")
        else:
            missing = [n for n, t in zip(names, types, strict=True) if t == rp.NOT_FOUND]
            self.log(f"rtde#{self.conn_id}: output setup with unknown variable(s) {missing}")
            recipe_id = 0
        self.send(rp.pack(rp.SETUP_OUTPUTS, bytes([recipe_id]) + ",".join(types).encode()))

    def _setup_inputs(self, payload: bytes) -> None:
        names = [n for n in payload.decode().split(",") if n]
        types = []
        for n in names:
            t = rp.INPUT_TYPES.get(n, rp.NOT_FOUND)
            if t != rp.NOT_FOUND and self.owners.get(n, self.conn_id) != self.conn_id:
                t = rp.IN_USE
            types.append(t)
        ok = bool(names) and all(t not in (rp.NOT_FOUND, rp.IN_USE) for t in types)
        recipe_id = 0
        if ok:
            recipe_id = len(self.inputs) + 1
            self.inputs[recipe_id] = (names, types, rp.recipe_struct(types))
            self.input_recipe_log.append(names)
            for n in names:
                self.owners[n] = self.conn_id
        else:
            self.log(f"rtde#{self.conn_id}: input setup refused: {dict(zip(names, types, strict=True))}")
        self.send(rp.pack(rp.SETUP_INPUTS, bytes([recipe_id]) + ",".join(types).encode()))

    def _input_package(self, payload: bytes, t_s: float) -> None:
        if not payload or payload[0] not in self.inputs:
            self.log(f"rtde#{self.conn_id}: data package for unknown input recipe {payload[:1].hex()}")
            return
        names, types, st = self.inputs[payload[0]]
        if len(payload) != st.size:
            self.log(f"rtde#{self.conn_id}: recipe {payload[0]} package of {len(payload)} bytes, expected {st.size}")
            return
        values = rp.unflatten(st.unpack(payload)[1:], types)
        for n, v in zip(names, values, strict=True):
            self.regs.write(n, v, t_s)
        self.regs.packages += 1
        self.regs.last_package_t_s = t_s
        self.regs.last_package_names = tuple(names)
        self.on_input(t_s)

    # ------------------------------------------------------------------ outbound
    def data_package(self, state: dict[str, object]) -> bytes:
        """The output recipe's data package for one controller state (registers read live)."""
        assert self.output_struct is not None
        values = []
        for n in self.output_names:
            v = state.get(n)
            values.append(self.regs.read_output(n) if v is None else v)
        flat = rp.flatten(values, self.output_types)
        return rp.pack(rp.DATA_PACKAGE, self.output_struct.pack(1, *flat))

    def send(self, data: bytes, release_t_s: float | None = None) -> None:
        """Queue bytes; with ``release_t_s`` they leave no earlier than that (packet-delay fault)."""
        if release_t_s is not None:
            self.delayed.append((release_t_s, data))
        else:
            self.outbox.extend(data)

    def flush(self, t_s: float) -> bool:
        """Send what is due; False if the connection must be closed (error or backlog)."""
        while self.delayed and self.delayed[0][0] <= t_s:
            self.outbox.extend(self.delayed.popleft()[1])
        if not self.outbox:
            return True
        try:
            n = self.sock.send(self.outbox)
        except BlockingIOError:
            n = 0
        except OSError:
            return False
        del self.outbox[:n]
        return len(self.outbox) < MAX_BACKLOG_BYTES

    def release(self) -> None:
        """Give up the input registers this connection owned and close the socket."""
        for n in [k for k, owner in self.owners.items() if owner == self.conn_id]:
            del self.owners[n]
        self.closed = True
        try:
            self.sock.close()
        except OSError:
            pass
