"""One RTDE client connection (TCP 30004) of the emulated controller: setup, recipes, streaming, inputs.

Input recipes are numbered 1, 2, 3, ... per connection in setup order (``ur_rtde`` hard-codes those ids);
an input register another live connection already owns is answered ``IN_USE``; an unknown name
``NOT_FOUND``. Data packages are streamed at the requested frequency (at most the CB3's 125 Hz) from the
controller cycle; input data packages are accepted before START as well (``RTDEIOInterface`` never starts).

A connection speaks protocol version 1 until it negotiates 2 (a CB3 accepts both): a version 1 output setup is
names only, its answer and data packages carry no recipe id, and it is served at 125 Hz. Input that breaks the
protocol never ends the emulator: a malformed package is answered with an error ``TEXT_MESSAGE`` (and, for a
request that expects an answer, with that answer's refusal: protocol version not accepted, recipe id 0), a
package stream whose framing is lost (size field below 3) gets the message and is closed, and each connection's
complaints go through the RTDE port's log budget (:class:`~drillgym.envs.real.emulator.nonblocking.LogBudget`).
"""

from __future__ import annotations

import math
import socket
import struct
from collections import deque
from collections.abc import Callable

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.nonblocking import Outbox
from drillgym.envs.real.emulator.registers import Registers

CONTROLLER_VERSION = (3, 15, 7, 106331)
"""PolyScope 3.15.7 (CB3): what ``GET_URCONTROL_VERSION`` answers; it selects ur_rtde's recipes and rates."""
CB3_RATE_HZ = 125.0
MAX_BACKLOG_BYTES = 1 << 20
"""A client that lets this much output pile up is disconnected (a real controller drops slow readers)."""
MAX_INPUT_RECIPES = 255
"""Input recipe ids are one byte and 0 means refused: at most 255 input recipes per connection."""


def output_divider(frequency_hz: float) -> int:
    """Controller cycles between output packages for a requested frequency (Hz).

    The frequency is clipped to the CB3's 1-125 Hz (UR's client library refuses more than 125 Hz on a CB3 before
    asking) and served every ``floor(125 / f)`` controller cycles, so never slower than requested: the rule
    issue 43 cites from UR's RTDE guide for CB-Series controllers (a CB3 has no 500 Hz mode; the e-Series'
    ``floor(500 / f)`` is not emulated). ``ValueError`` for a frequency that is not a number.
    """
    if math.isnan(frequency_hz):
        raise ValueError("RTDE output frequency is not a number")
    rate = min(max(frequency_hz, 1.0), CB3_RATE_HZ)
    return max(math.floor(CB3_RATE_HZ / rate + 1e-9), 1)  # 1e-9: 125 / (125 / 7) is 6.999...


class RtdeConnection:
    """Protocol state of one RTDE client.

    Args:
        sock: the accepted socket (non-blocking).
        registers: the controller's register file.
        owners: input field name -> owning connection id (shared by all connections).
        conn_id: this connection's id.
        log: called with one line per notable event.
        on_input: called after every input data package (with the emulator time).
        complaints: where the lines about protocol errors go (default ``log``; the server passes the RTDE port's
            log budget, shared by every RTDE client).
    """

    def __init__(
        self,
        sock: socket.socket,
        registers: Registers,
        owners: dict[str, int],
        conn_id: int,
        log: Callable[[str], None],
        on_input: Callable[[float], None] = lambda t_s: None,
        complaints: Callable[[str], None] | None = None,
    ) -> None:
        self.sock = sock
        self.regs = registers
        self.owners = owners
        self.conn_id = conn_id
        self.log = log
        self._complaints = complaints or log
        self.on_input = on_input
        self.reader = rp.PackageReader()
        self.protocol_version = 1
        self.output_names: list[str] = []
        self.output_types: list[str] = []
        self.output_struct: struct.Struct | None = None
        self.output_recipe_id = True
        """Whether output data packages carry the recipe id (protocol version 2 at setup)."""
        self.divider = 1
        self.started = False
        self.inputs: dict[int, tuple[list[str], list[str], struct.Struct]] = {}
        self.outbox = Outbox(sock, MAX_BACKLOG_BYTES)
        self.delayed: deque[tuple[float, bytes]] = deque()
        self.sent_packages = 0
        self.input_recipe_log: list[list[str]] = []
        self.closed = False

    # ------------------------------------------------------------------ inbound
    def receive(self, data: bytes, t_s: float) -> None:
        """Handle received bytes (any number of packages); ``ValueError`` once the framing is lost.

        The packages complete before a broken header are handled first, in order, as a controller reading the
        stream package by package would.
        """
        lost: rp.FramingError | None = None
        try:
            packages = self.reader.feed(data)
        except rp.FramingError as e:
            packages, lost = e.packages, e
        for kind, payload in packages:
            self._handle(kind, payload, t_s)
        if lost is not None:
            self.refuse(f"{lost}; closing")
            raise lost

    def complain(self, line: str) -> None:
        """One line about this client's protocol errors, to the complaints log."""
        self._complaints(f"rtde#{self.conn_id}: {line}")

    def refuse(self, reason: str) -> None:
        """Log ``reason`` (within the budget) and send it to the client as an error ``TEXT_MESSAGE``."""
        self.complain(reason)
        self.send(rp.text_message(reason, rp.ERROR_MESSAGE, self.protocol_version))

    def _handle(self, kind: int, payload: bytes, t_s: float) -> None:
        if kind == rp.REQUEST_PROTOCOL_VERSION:
            self._negotiate(payload)
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
        elif kind == rp.TEXT_MESSAGE:
            self.complain(f"client message {payload[:200]!r}")
        else:
            self.refuse(f"unknown package type {kind}")

    def _negotiate(self, payload: bytes) -> None:
        """``REQUEST_PROTOCOL_VERSION``: ``uint16`` version in, ``uint8`` accepted out; the version stays on refusal."""
        if len(payload) != 2:
            self.refuse(f"REQUEST_PROTOCOL_VERSION with a {len(payload)}-byte payload, expected a uint16")
            accepted = False
        else:
            version = struct.unpack(">H", payload)[0]
            accepted = version in rp.PROTOCOL_VERSIONS
            if accepted:
                self.protocol_version = version
            else:
                self.complain(f"protocol version {version} refused (a CB3 speaks {rp.PROTOCOL_VERSIONS})")
        self.send(rp.pack(rp.REQUEST_PROTOCOL_VERSION, bytes([1 if accepted else 0])))

    def _answer_setup(self, kind: int, recipe_id: int | None, types: list[str]) -> None:
        """The answer to a setup: recipe id (None: version 1 outputs have none) and types; refused if too long."""
        head = b"" if recipe_id is None else bytes([recipe_id])
        body = ",".join(types).encode()
        if rp.HEADER.size + len(head) + len(body) > rp.MAX_PACKAGE_BYTES:
            self.refuse(f"setup of {len(types)} variables: its answer would not fit one package")
            head, body = (b"" if recipe_id is None else b"\x00"), b""
        self.send(rp.pack(kind, head + body))

    def _setup_outputs(self, payload: bytes) -> None:
        v2 = self.protocol_version == 2
        no_id = None if not v2 else 0
        if v2 and len(payload) < 8:
            self.refuse(f"SETUP_OUTPUTS with a {len(payload)}-byte payload, shorter than its 8-byte output frequency")
            self._answer_setup(rp.SETUP_OUTPUTS, no_id, [])
            return
        frequency = struct.unpack_from(">d", payload)[0] if v2 else CB3_RATE_HZ
        names = [n for n in payload[8 if v2 else 0 :].decode(errors="replace").split(",") if n]
        types = [rp.OUTPUT_TYPES.get(n, rp.NOT_FOUND) for n in names]
        if math.isnan(frequency):
            self.refuse("SETUP_OUTPUTS with a frequency that is not a number")
            self._answer_setup(rp.SETUP_OUTPUTS, no_id, types)
            return
        if rp.NOT_FOUND in types or not names:
            missing = [n for n, t in zip(names, types, strict=True) if t == rp.NOT_FOUND]
            self.complain(f"output setup with unknown variable(s) {missing[:10]}" if names else "empty output setup")
            self._answer_setup(rp.SETUP_OUTPUTS, no_id, types)
            return
        st = rp.recipe_struct(types, recipe_id=v2)
        if rp.HEADER.size + st.size > rp.MAX_PACKAGE_BYTES:
            self.refuse(f"output recipe of {len(names)} variables: its data package would not fit one package")
            self._answer_setup(rp.SETUP_OUTPUTS, no_id, types)
            return
        self.output_names, self.output_types, self.output_struct, self.output_recipe_id = names, types, st, v2
        self.divider = output_divider(frequency)
        served_hz = CB3_RATE_HZ / self.divider
        if abs(served_hz - frequency) > 1e-9:
            self.log(
                f"rtde#{self.conn_id}: {frequency:g} Hz requested, served every {self.divider} controller cycle(s) "
                f"({served_hz:.4g} Hz: floor(125 / f) cycles, f clipped to 1-125 Hz"
                + ("; protocol version 1 has no frequency" if not v2 else "")
                + ")"
            )
        constant = [n for n in names if n in rp.NOT_EMULATED]
        if constant:
            self.log(f"rtde#{self.conn_id}: outputs not emulated (served as constants): {', '.join(constant)}")
        self._answer_setup(rp.SETUP_OUTPUTS, 1 if v2 else None, types)

    def _setup_inputs(self, payload: bytes) -> None:
        names = [n for n in payload.decode(errors="replace").split(",") if n]
        types = []
        for n in names:
            t = rp.INPUT_TYPES.get(n, rp.NOT_FOUND)
            if t != rp.NOT_FOUND and self.owners.get(n, self.conn_id) != self.conn_id:
                t = rp.IN_USE
            types.append(t)
        ok = bool(names) and all(t not in (rp.NOT_FOUND, rp.IN_USE) for t in types)
        recipe_id = 0
        if ok and len(self.inputs) >= MAX_INPUT_RECIPES:
            self.refuse(f"input setup refused: {MAX_INPUT_RECIPES} input recipes already set up")
        elif ok and rp.HEADER.size + rp.recipe_struct(types).size > rp.MAX_PACKAGE_BYTES:
            self.refuse(f"input recipe of {len(names)} variables: its data package would not fit one package")
        elif ok:
            recipe_id = len(self.inputs) + 1
            self.inputs[recipe_id] = (names, types, rp.recipe_struct(types))
            self.input_recipe_log.append(names)
            for n in names:
                self.owners[n] = self.conn_id
        else:
            refused = {n: t for n, t in zip(names, types, strict=True) if t in (rp.NOT_FOUND, rp.IN_USE)}
            self.complain(f"input setup refused: {dict(list(refused.items())[:10]) if names else 'no variables'}")
        self._answer_setup(rp.SETUP_INPUTS, recipe_id, types)

    def _input_package(self, payload: bytes, t_s: float) -> None:
        if not payload or payload[0] not in self.inputs:
            self.refuse(f"data package for unknown input recipe {payload[:1].hex() or '(none)'}")
            return
        names, types, st = self.inputs[payload[0]]
        if len(payload) != st.size:
            self.refuse(f"recipe {payload[0]} package of {len(payload)} bytes, expected {st.size}")
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
        head = (1,) if self.output_recipe_id else ()
        return rp.pack(rp.DATA_PACKAGE, self.output_struct.pack(*head, *flat))

    def send(self, data: bytes, release_t_s: float | None = None) -> None:
        """Queue bytes; with ``release_t_s`` they leave no earlier than that (packet-delay fault)."""
        if release_t_s is not None:
            self.delayed.append((release_t_s, data))
        else:
            self.outbox.queue(data)

    def flush(self, t_s: float) -> bool:
        """Send what is due without waiting; False if the connection must be closed (error or backlog)."""
        while self.delayed and self.delayed[0][0] <= t_s:
            self.outbox.queue(self.delayed.popleft()[1])
        return self.outbox.flush()

    def release(self) -> None:
        """Give up the input registers this connection owned and close the socket."""
        for n in [k for k, owner in self.owners.items() if owner == self.conn_id]:
            del self.owners[n]
        self.closed = True
        try:
            self.sock.close()
        except OSError:
            pass
