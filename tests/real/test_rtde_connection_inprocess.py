"""One emulated RTDE client connection (``envs/real/emulator/rtde_server.py``), driven in-process byte by byte.

No subprocess, no listening socket, no waiting: :class:`RtdeConnection` is built on a fake socket that keeps what
the connection sends, fed packages packed here by hand, and its answers are split here with a parser of our own
(never the module's ``pack``, ``PackageReader`` or type tables), so every expected byte is an independent oracle.

Oracle: UR's RTDE guide ("Real-Time Data Exchange (RTDE) Guide"), its package tables. A package is ``uint16`` size
(the 3-byte header included), ``uint8`` type, payload, big-endian:

- RTDE_REQUEST_PROTOCOL_VERSION ``V`` (86): ``uint16`` version in; ``uint8`` accepted (1) or not (0) out.
- RTDE_GET_URCONTROL_VERSION ``v`` (118): out ``uint32`` major, minor, bugfix, build.
- RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS ``O`` (79): version 2 ``double`` output frequency then the comma-separated
  variable names, answered with ``uint8`` output recipe id and the comma-separated types (``NOT_FOUND`` for an
  unknown name); version 1 names only, answered with the types only.
- RTDE_CONTROL_PACKAGE_SETUP_INPUTS ``I`` (73): names in; ``uint8`` input recipe id (0: refused) and the types
  (``IN_USE`` for a field another client owns) out.
- RTDE_CONTROL_PACKAGE_START ``S`` (83) and PAUSE ``P`` (80): ``uint8`` accepted out.
- RTDE_DATA_PACKAGE ``U`` (85): ``uint8`` recipe id (none in a version 1 output package), then the fields packed
  back to back: BOOL and UINT8 1 byte, INT32 and UINT32 4, UINT64 and DOUBLE 8, VECTOR3D 3 DOUBLE, VECTOR6D 6
  DOUBLE, VECTOR6INT32 6 INT32.
- RTDE_TEXT_MESSAGE ``M`` (77): version 2 ``uint8`` message length, message, ``uint8`` source length, source,
  ``uint8`` warning level (EXCEPTION 0, ERROR 1, WARNING 2, INFO 3); version 1 ``uint8`` message type, message.

The same layouts as UR's Client Library reads them (``src/rtde/*.cpp``) and UR's Python client
(``rtde/serialize.py``). Output rate on a CB3: a package every ``floor(125 / f)`` controller cycles for a requested
``f`` clipped to 1-125 Hz (the rule ``tests/real/test_rtde_divider.py`` pins and cites). Which malformed requests
get a text message, and the wording of the messages and log lines, are the emulator's own (docs/deployment.md §6);
they are pinned here word for word so that a changed refusal shows in review.
"""

from __future__ import annotations

import struct

import pytest

from drillgym.envs.real.emulator.registers import Registers
from drillgym.envs.real.emulator.rtde_server import RtdeConnection, output_divider

CONN_ID = 7


class FakeSocket:
    """The accepted socket, as far as a connection uses it: ``send`` keeps the bytes, ``close`` is recorded.

    ``accept`` limits the bytes one ``send`` takes (None: all); ``send_error`` is raised by ``send`` instead.
    """

    def __init__(self) -> None:
        self.sent = bytearray()
        self.accept: int | None = None
        self.send_error: OSError | None = None
        self.close_error: OSError | None = None
        self.closed = False

    def send(self, data: bytes) -> int:
        if self.send_error is not None:
            raise self.send_error
        n = len(data) if self.accept is None else min(self.accept, len(data))
        self.sent += data[:n]
        return n

    def close(self) -> None:
        self.closed = True
        if self.close_error is not None:
            raise self.close_error


def package(kind: str, payload: bytes = b"") -> bytes:
    """One RTDE package written out by hand: ``uint16`` size with the header, ``uint8`` type, payload."""
    return struct.pack(">HB", 3 + len(payload), ord(kind)) + payload


def split(data: bytes) -> list[tuple[str, bytes]]:
    """The packages in ``data`` as (type letter, payload); the sizes must add up to the data exactly."""
    out, i = [], 0
    while i < len(data):
        size, kind = struct.unpack_from(">HB", data, i)
        assert size >= 3 and i + size <= len(data), "a package's size field runs past what was sent"
        out.append((chr(kind), bytes(data[i + 3 : i + size])))
        i += size
    return out


def v1_text(payload: bytes) -> tuple[int, str]:
    """(level, message) of a version 1 TEXT_MESSAGE."""
    return payload[0], payload[1:].decode()


def v2_text(payload: bytes) -> tuple[str, str, int]:
    """(message, source, level) of a version 2 TEXT_MESSAGE, checking that its length fields add up."""
    n = payload[0]
    m = payload[1 + n]
    assert len(payload) == 3 + n + m, "length fields and payload disagree"
    return payload[1 : 1 + n].decode(), payload[2 + n : 2 + n + m].decode(), payload[-1]


class Client:
    """A connection on a fake socket, with its log, complaints and input callbacks recorded."""

    def __init__(
        self,
        owners: dict[str, int] | None = None,
        conn_id: int = CONN_ID,
        registers: Registers | None = None,
        budget: bool = True,
    ) -> None:
        self.sock = FakeSocket()
        self.regs = registers if registers is not None else Registers()
        self.owners: dict[str, int] = owners if owners is not None else {}
        self.log: list[str] = []
        self.complaints: list[str] = []
        self.input_times: list[float] = []
        self.conn = RtdeConnection(
            self.sock,  # type: ignore[arg-type]
            self.regs,
            self.owners,
            conn_id,
            self.log.append,
            self.input_times.append,
            self.complaints.append if budget else None,
        )

    def send(self, kind: str, payload: bytes = b"", t_s: float = 0.0) -> list[tuple[str, bytes]]:
        """Feed one package; the packages the connection answers with."""
        return self.feed(package(kind, payload), t_s)

    def feed(self, data: bytes, t_s: float = 0.0) -> list[tuple[str, bytes]]:
        self.conn.receive(data, t_s)
        return self.replies(t_s)

    def replies(self, t_s: float = 0.0) -> list[tuple[str, bytes]]:
        assert self.conn.flush(t_s) is True
        out = split(bytes(self.sock.sent))
        self.sock.sent.clear()
        return out

    def negotiate(self, version: int) -> None:
        assert self.send("V", struct.pack(">H", version)) == [("V", b"\x01")]


def v2_outputs(frequency_hz: float, names: str) -> bytes:
    """A version 2 SETUP_OUTPUTS payload: ``double`` frequency, then the names."""
    return struct.pack(">d", frequency_hz) + names.encode()


# ---------------------------------------------------------------------------------------------- a new connection
def test_a_fresh_connection_speaks_version_1_streams_nothing_and_owns_nothing():
    c = Client()
    assert c.conn.protocol_version == 1
    assert c.conn.started is False and c.conn.closed is False
    assert c.conn.output_struct is None and c.conn.output_names == [] and c.conn.output_types == []
    assert c.conn.inputs == {} and c.conn.input_recipe_log == [] and c.conn.sent_packages == 0
    assert c.replies() == []
    assert c.log == [] and c.complaints == []


def test_complaints_go_to_the_budget_and_notes_to_the_log():
    c = Client()
    c.send("Z")
    c.send("O", b"target_qdd")
    assert c.complaints == ["rtde#7: unknown package type 90"]
    assert c.log == ["rtde#7: outputs not emulated (served as constants): target_qdd"]


def test_complaints_go_to_the_log_when_no_budget_is_given():
    c = Client(budget=False, conn_id=3)
    c.send("Z")
    assert c.log == ["rtde#3: unknown package type 90"]


# ---------------------------------------------------------------------------------------------- protocol version
@pytest.mark.parametrize("version", [1, 2])
def test_protocol_versions_1_and_2_are_accepted(version):
    c = Client()
    assert c.send("V", struct.pack(">H", version)) == [("V", b"\x01")]
    assert c.conn.protocol_version == version
    assert c.complaints == []


@pytest.mark.parametrize("version", [0, 3, 0x0102, 0xFFFF])
def test_other_protocol_versions_are_refused_and_the_version_stays(version):
    c = Client()
    assert c.send("V", struct.pack(">H", version)) == [("V", b"\x00")]
    assert c.conn.protocol_version == 1
    c.negotiate(2)
    assert c.send("V", struct.pack(">H", version)) == [("V", b"\x00")]
    assert c.conn.protocol_version == 2
    assert c.complaints == [f"rtde#7: protocol version {version} refused (a CB3 speaks (1, 2))"] * 2


@pytest.mark.parametrize("payload", [b"", b"\x02", b"\x00\x02\x00"])
def test_a_version_request_that_is_not_a_uint16_gets_an_error_message_and_is_refused(payload):
    c = Client()
    (kind, text), answer = c.send("V", payload)
    reason = f"REQUEST_PROTOCOL_VERSION with a {len(payload)}-byte payload, expected a uint16"
    assert kind == "M" and v1_text(text) == (1, reason)
    assert answer == ("V", b"\x00")
    assert c.conn.protocol_version == 1
    assert c.complaints == [f"rtde#7: {reason}"]


def test_controller_version_is_polyscope_3_15_7():
    """Four ``uint32`` (major, minor, bugfix, build): 3.15.7.106331, a CB3 (ur_rtde picks its recipes by it)."""
    c = Client()
    assert c.feed(package("v")) == [("v", bytes.fromhex("00000003 0000000f 00000007 00019f5b"))]


# ---------------------------------------------------------------------------------------------- SETUP_OUTPUTS
ALL_OUTPUT_KINDS = (
    "timestamp,actual_q,payload_cog,robot_mode,runtime_state,actual_digital_output_bits,joint_mode,"
    "output_int_register_2,output_double_register_1,input_double_register_3,input_int_register_4"
)
ALL_OUTPUT_TYPES = b"DOUBLE,VECTOR6D,VECTOR3D,INT32,UINT32,UINT64,VECTOR6INT32,INT32,DOUBLE,DOUBLE,INT32"


def test_version_2_output_setup_answers_recipe_1_and_the_types():
    c = Client()
    c.negotiate(2)
    assert c.send("O", v2_outputs(125.0, ALL_OUTPUT_KINDS)) == [("O", b"\x01" + ALL_OUTPUT_TYPES)]
    assert c.conn.output_names == ALL_OUTPUT_KINDS.split(",")
    assert c.conn.divider == 1
    assert c.log == [] and c.complaints == []


def test_version_1_output_setup_is_names_only_answered_with_types_only():
    c = Client()
    assert c.send("O", ALL_OUTPUT_KINDS.encode()) == [("O", ALL_OUTPUT_TYPES)]
    assert c.conn.output_names == ALL_OUTPUT_KINDS.split(",")
    assert c.conn.divider == 1
    c.negotiate(1)
    assert c.send("O", b"timestamp") == [("O", b"DOUBLE")]
    assert c.log == [] and c.complaints == []


def test_empty_names_between_commas_are_skipped():
    c = Client()
    assert c.send("O", b",timestamp,,actual_q,") == [("O", b"DOUBLE,VECTOR6D")]
    assert c.conn.output_names == ["timestamp", "actual_q"]


def test_an_unknown_output_is_not_found_and_the_setup_is_not_taken():
    """``ft_raw_wrench`` is e-Series only: a CB3 answers NOT_FOUND, recipe id 0, and has no recipe to START."""
    c = Client()
    c.negotiate(2)
    assert c.send("O", v2_outputs(125.0, "timestamp,ft_raw_wrench")) == [("O", b"\x00DOUBLE,NOT_FOUND")]
    assert c.conn.output_struct is None and c.conn.output_names == []
    assert c.send("S") == [("S", b"\x00")] and c.conn.started is False
    assert c.complaints == ["rtde#7: output setup with unknown variable(s) ['ft_raw_wrench']"]


def test_a_failed_output_setup_keeps_the_recipe_before_it():
    c = Client()
    c.negotiate(2)
    c.send("O", v2_outputs(25.0, "timestamp"))
    assert c.send("O", v2_outputs(125.0, "actual_q,nope")) == [("O", b"\x00VECTOR6D,NOT_FOUND")]
    assert c.conn.output_names == ["timestamp"] and c.conn.divider == 5


def test_an_unknown_output_in_version_1_is_not_found_without_a_recipe_id():
    c = Client()
    assert c.send("O", b"nope,timestamp") == [("O", b"NOT_FOUND,DOUBLE")]
    assert c.conn.output_struct is None


def test_names_that_are_not_utf8_are_not_found():
    c = Client()
    assert c.send("O", b"timestamp,\xff\xfe") == [("O", b"DOUBLE,NOT_FOUND")]
    assert c.complaints == ["rtde#7: output setup with unknown variable(s) ['\ufffd\ufffd']"]


def test_the_unknown_outputs_complaint_names_the_first_ten():
    c = Client()
    names = ",".join(f"n{i}" for i in range(12))
    assert c.send("O", names.encode()) == [("O", b",".join([b"NOT_FOUND"] * 12))]
    assert c.complaints == [f"rtde#7: output setup with unknown variable(s) {[f'n{i}' for i in range(10)]}"]


def test_an_empty_version_2_output_setup_is_answered_recipe_0_without_types():
    """Exactly the 8-byte frequency and no names: not malformed, just empty (no error message)."""
    c = Client()
    c.negotiate(2)
    assert c.send("O", struct.pack(">d", 125.0)) == [("O", b"\x00")]
    assert c.send("O", struct.pack(">d", 125.0) + b",,") == [("O", b"\x00")]
    assert c.complaints == ["rtde#7: empty output setup"] * 2
    assert c.conn.output_struct is None


def test_an_empty_version_1_output_setup_is_answered_without_types():
    c = Client()
    assert c.send("O") == [("O", b"")]
    assert c.complaints == ["rtde#7: empty output setup"]


@pytest.mark.parametrize("size", [0, 7])
def test_a_version_2_output_setup_shorter_than_its_frequency_gets_an_error_message(size):
    """Version 2 messages: (message, source "RTDE", level ERROR 1), then recipe id 0 and no types."""
    c = Client()
    c.negotiate(2)
    (kind, text), answer = c.send("O", b"\x40" * size)
    reason = f"SETUP_OUTPUTS with a {size}-byte payload, shorter than its 8-byte output frequency"
    assert kind == "M" and v2_text(text) == (reason, "RTDE", 1)
    assert answer == ("O", b"\x00")
    assert c.complaints == [f"rtde#7: {reason}"]
    assert c.conn.output_struct is None


def test_a_version_2_output_setup_with_a_nan_frequency_is_refused_with_its_types():
    c = Client()
    c.negotiate(2)
    (kind, text), answer = c.send("O", struct.pack(">d", float("nan")) + b"timestamp,nope")
    assert kind == "M" and v2_text(text) == ("SETUP_OUTPUTS with a frequency that is not a number", "RTDE", 1)
    assert answer == ("O", b"\x00DOUBLE,NOT_FOUND")
    assert c.conn.output_struct is None


def test_outputs_served_as_constants_are_logged():
    c = Client()
    assert c.send("O", b"target_qdd,timestamp,io_current") == [("O", b"VECTOR6D,DOUBLE,DOUBLE")]
    assert c.log == ["rtde#7: outputs not emulated (served as constants): target_qdd, io_current"]


# The largest output recipe: 1365 VECTOR6D (65520 bytes) + INT32 + DOUBLE = 65532 bytes of fields.
BIG_OUTPUTS = ",".join(["actual_q"] * 1365 + ["robot_mode", "timestamp"])


def test_a_version_1_output_recipe_whose_data_package_is_65535_bytes_is_taken():
    """Version 1 has no recipe id: 3 + 65532 = 65535 bytes, the uint16 size field's largest."""
    c = Client()
    [(kind, answer)] = c.send("O", BIG_OUTPUTS.encode())
    assert kind == "O" and answer == b"VECTOR6D," * 1365 + b"INT32,DOUBLE"
    state = {"actual_q": (0.0,) * 6, "robot_mode": 7, "timestamp": 1.0}
    data = c.conn.data_package(state)
    assert len(data) == 65535 and data[:3] == b"\xff\xffU"
    assert data[-12:] == struct.pack(">i", 7) + struct.pack(">d", 1.0)


def test_an_output_recipe_whose_data_package_would_not_fit_is_refused():
    """4 bytes over in version 1 (one INT32 more); in version 2 the recipe id byte alone takes it to 65536."""
    c = Client()
    names = BIG_OUTPUTS + ",safety_mode"
    (kind, text), (akind, answer) = c.send("O", names.encode())
    reason = "output recipe of 1368 variables: its data package would not fit one package"
    assert kind == "M" and v1_text(text) == (1, reason)
    assert akind == "O" and answer == b"VECTOR6D," * 1365 + b"INT32,DOUBLE,INT32"
    assert c.conn.output_struct is None
    c.negotiate(2)
    (kind, text), (akind, answer) = c.send("O", v2_outputs(125.0, BIG_OUTPUTS))
    reason = "output recipe of 1367 variables: its data package would not fit one package"
    assert kind == "M" and v2_text(text) == (reason, "RTDE", 1)
    assert akind == "O" and answer == b"\x00" + b"VECTOR6D," * 1365 + b"INT32,DOUBLE"
    assert c.conn.output_struct is None
    assert c.complaints == [
        f"rtde#7: output recipe of {n} variables: its data package would not fit one package" for n in (1368, 1367)
    ]


def _unknown_and_doubles(unknown: int, doubles: int) -> str:
    return ",".join(["x"] * unknown + ["timestamp"] * doubles)


@pytest.mark.parametrize(("version", "unknown", "doubles"), [(2, 6549, 6), (1, 6547, 9)])
def test_a_setup_answer_of_65535_bytes_is_sent_whole(version, unknown, doubles):
    """Answer size: 3 + id byte (version 2) + 9 per NOT_FOUND, 6 per DOUBLE, a comma between: 65535 exactly."""
    c = Client()
    c.negotiate(version)
    names = _unknown_and_doubles(unknown, doubles)
    [(kind, answer)] = c.send("O", v2_outputs(125.0, names) if version == 2 else names.encode())
    head = b"\x00" if version == 2 else b""
    assert kind == "O" and answer == head + b",".join([b"NOT_FOUND"] * unknown + [b"DOUBLE"] * doubles)
    assert 3 + len(answer) == 65535


@pytest.mark.parametrize(("version", "unknown", "doubles"), [(2, 6547, 9), (1, 6552, 2)])
def test_a_setup_answer_over_65535_bytes_is_refused_with_an_empty_answer(version, unknown, doubles):
    c = Client()
    c.negotiate(version)
    names = _unknown_and_doubles(unknown, doubles)
    (kind, text), answer = c.send("O", v2_outputs(125.0, names) if version == 2 else names.encode())
    reason = f"setup of {unknown + doubles} variables: its answer would not fit one package"
    assert kind == "M" and (v2_text(text) == (reason, "RTDE", 1) if version == 2 else v1_text(text) == (1, reason))
    assert answer == ("O", b"\x00" if version == 2 else b"")
    assert c.complaints[-1] == f"rtde#7: {reason}"


# ---------------------------------------------------------------------------------------------- the divider
DIVIDER_TABLE = [
    # requested Hz, floor(125 / f) cycles, the log line (None: served at exactly the requested rate)
    (25.0, 5, None),
    (40.0, 3, "40 Hz requested, served every 3 controller cycle(s) (41.67 Hz"),
    (60.0, 2, "60 Hz requested, served every 2 controller cycle(s) (62.5 Hz"),
    (100.0, 1, "100 Hz requested, served every 1 controller cycle(s) (125 Hz"),
    (124.5, 1, "124.5 Hz requested, served every 1 controller cycle(s) (125 Hz"),
    (125.0, 1, None),
    (125.0 / 3.0, 3, None),  # 41.67 Hz is served exactly (125 / (125 / 3) is 3 to within an ulp)
    (500.0, 1, "500 Hz requested, served every 1 controller cycle(s) (125 Hz"),
    (-5.0, 125, "-5 Hz requested, served every 125 controller cycle(s) (1 Hz"),
]


@pytest.mark.parametrize(("frequency_hz", "divider", "line"), DIVIDER_TABLE)
def test_a_version_2_setup_is_served_every_floor_125_over_f_cycles(frequency_hz, divider, line):
    """The divider the setup leaves, and the log line when the served rate is not the requested one.

    The table's rates: 124.5 Hz is logged (served 0.5 Hz faster), 125 / 3 Hz is not (served to within 1e-14).
    """
    c = Client()
    c.negotiate(2)
    assert c.send("O", v2_outputs(frequency_hz, "timestamp")) == [("O", b"\x01DOUBLE")]
    assert c.conn.divider == divider
    expected = [] if line is None else [f"rtde#7: {line}: floor(125 / f) cycles, f clipped to 1-125 Hz)"]
    assert c.log == expected


def test_the_divider_of_a_frequency_that_is_not_a_number_is_refused_by_name():
    with pytest.raises(ValueError, match=r"^RTDE output frequency is not a number$"):
        output_divider(float("nan"))


@pytest.fixture(scope="module")
def emulator():
    """One emulator object, never started: no port is opened, its controller cycle is called by hand."""
    from drillgym.envs.real.emulator.config import EmulatorConfig
    from drillgym.envs.real.emulator.server import Emulator

    emu = Emulator(EmulatorConfig())
    emu.log = lambda line: None  # type: ignore[method-assign]
    return emu


@pytest.mark.parametrize(
    ("frequency_hz", "cycles"),
    [
        (25.0, [5, 10, 15, 20, 25, 30]),
        (40.0, [3, 6, 9, 12, 15, 18, 21, 24, 27, 30]),
        (60.0, list(range(2, 31, 2))),
        (100.0, list(range(1, 31))),
        (125.0, list(range(1, 31))),
    ],
)
def test_the_controller_cycles_that_carry_a_data_package(emulator, frequency_hz, cycles):
    """Cycles 1-30 of the emulator's 8 ms controller (counted from 0 here) that send the recipe's package."""
    c = Client(registers=emulator.regs, owners=emulator.owners)
    c.negotiate(2)
    c.send("O", v2_outputs(frequency_hz, "timestamp,robot_mode"))
    assert c.send("S") == [("S", b"\x01")]
    emulator.rtde.append(c.conn)
    emulator.controller_ticks = 0
    sent = []
    try:
        for k in range(1, 31):
            before = c.conn.sent_packages
            emulator.controller_tick(k * 0.008)
            if c.conn.sent_packages > before:
                sent.append(k)
    finally:
        emulator.rtde.remove(c.conn)
    assert sent == cycles
    packages = c.replies(1.0)
    assert [k for k, _ in packages] == ["U"] * len(cycles)
    assert all(len(p) == 1 + 8 + 4 and p[0] == 1 for _, p in packages)


# ---------------------------------------------------------------------------------------------- data packages
STATE = {
    "timestamp": 12.5,
    "actual_q": (0.1, -0.2, 0.3, -0.4, 0.5, -0.6),
    "payload_cog": (0.01, 0.02, 0.03),
    "robot_mode": 7,
    "runtime_state": 2,
    "actual_digital_output_bits": 0x0102030405060708,
    "joint_mode": (253, 253, 253, 253, 253, -1),
}


def _expected_fields(out_int2: int, out_double1: float, in_double3: float, in_int4: int) -> bytes:
    """STATE's fields then the four registers, packed from the guide's types by hand."""
    return (
        struct.pack(">d", 12.5)
        + struct.pack(">dddddd", 0.1, -0.2, 0.3, -0.4, 0.5, -0.6)
        + struct.pack(">ddd", 0.01, 0.02, 0.03)
        + struct.pack(">i", 7)
        + struct.pack(">I", 2)
        + bytes.fromhex("0102030405060708")
        + struct.pack(">iiiiii", 253, 253, 253, 253, 253, -1)
        + struct.pack(">i", out_int2)
        + struct.pack(">d", out_double1)
        + struct.pack(">d", in_double3)
        + struct.pack(">i", in_int4)
    )


def test_version_2_data_package_is_recipe_id_then_every_type_in_order():
    regs = Registers()
    regs.output_int[2], regs.output_double[1], regs.input_double[3], regs.input_int[4] = -5, 2.5, -0.75, 9
    c = Client(registers=regs)
    c.negotiate(2)
    c.send("O", v2_outputs(125.0, ALL_OUTPUT_KINDS))
    data = c.conn.data_package(STATE)
    fields = _expected_fields(-5, 2.5, -0.75, 9)
    assert data == struct.pack(">HB", 3 + 1 + len(fields), ord("U")) + b"\x01" + fields
    assert len(fields) == 8 + 48 + 24 + 4 + 4 + 8 + 24 + 4 + 8 + 8 + 4


def test_version_1_data_package_has_no_recipe_id():
    regs = Registers()
    regs.output_int[2] = 3
    c = Client(registers=regs)
    c.send("O", ALL_OUTPUT_KINDS.encode())
    fields = _expected_fields(3, 0.0, 0.0, 0)
    assert c.conn.data_package(STATE) == struct.pack(">HB", 3 + len(fields), ord("U")) + fields


def test_registers_are_read_live_and_a_state_value_wins_over_a_register():
    regs = Registers()
    c = Client(registers=regs)
    c.negotiate(2)
    c.send("O", v2_outputs(125.0, "output_int_register_0,output_double_register_47"))
    regs.output_int[0], regs.output_double[47] = 11, 1.25
    assert c.conn.data_package({}) == b"\x00\x10U\x01" + struct.pack(">id", 11, 1.25)
    regs.output_int[0] = -1
    assert c.conn.data_package({}) == b"\x00\x10U\x01" + struct.pack(">id", -1, 1.25)
    assert c.conn.data_package({"output_int_register_0": 0}) == b"\x00\x10U\x01" + struct.pack(">id", 0, 1.25)


# ---------------------------------------------------------------------------------------------- START / PAUSE
def test_start_needs_an_output_recipe_and_pause_always_succeeds():
    c = Client()
    assert c.send("P") == [("P", b"\x01")]
    assert c.send("S") == [("S", b"\x00")] and c.conn.started is False
    c.send("O", b"timestamp")
    assert c.send("S") == [("S", b"\x01")] and c.conn.started is True
    assert c.send("S") == [("S", b"\x01")] and c.conn.started is True
    assert c.send("P") == [("P", b"\x01")] and c.conn.started is False
    assert c.send("S") == [("S", b"\x01")] and c.conn.started is True
    assert c.complaints == []


# ---------------------------------------------------------------------------------------------- SETUP_INPUTS
def test_input_recipes_are_numbered_1_2_3_in_setup_order():
    """``ur_rtde`` hard-codes the ids of its input recipes: they must come 1, 2, 3 per connection."""
    c = Client()
    assert c.send("I", b"input_int_register_0,input_double_register_1") == [("I", b"\x01INT32,DOUBLE")]
    assert c.send("I", b"input_bit_registers0_to_31,standard_digital_output") == [("I", b"\x02UINT32,UINT8")]
    assert c.send("I", b"external_force_torque,input_int_register_0") == [("I", b"\x03VECTOR6D,INT32")]
    assert c.conn.input_recipe_log == [
        ["input_int_register_0", "input_double_register_1"],
        ["input_bit_registers0_to_31", "standard_digital_output"],
        ["external_force_torque", "input_int_register_0"],
    ]
    assert sorted(c.conn.inputs) == [1, 2, 3]
    assert c.owners == {
        "input_int_register_0": 7,
        "input_double_register_1": 7,
        "input_bit_registers0_to_31": 7,
        "standard_digital_output": 7,
        "external_force_torque": 7,
    }
    assert c.complaints == []


def test_an_unknown_input_is_not_found_and_refused_with_recipe_0():
    c = Client()
    assert c.send("I", b"input_int_register_0,nope,,\xff") == [("I", b"\x00INT32,NOT_FOUND,NOT_FOUND")]
    assert c.conn.inputs == {} and c.owners == {}
    assert c.complaints == ["rtde#7: input setup refused: {'nope': 'NOT_FOUND', '\ufffd': 'NOT_FOUND'}"]
    assert c.send("I", b"input_int_register_0") == [("I", b"\x01INT32")]


def test_an_empty_input_setup_is_refused_with_recipe_0():
    c = Client()
    assert c.send("I", b",") == [("I", b"\x00")]
    assert c.complaints == ["rtde#7: input setup refused: no variables"]


def test_the_refused_inputs_complaint_names_the_first_ten():
    c = Client()
    names = [f"n{i}" for i in range(12)]
    c.send("I", ",".join(names).encode())
    assert c.complaints == [f"rtde#7: input setup refused: { {n: 'NOT_FOUND' for n in names[:10]} }"]


def test_an_input_another_connection_owns_is_in_use_until_it_lets_go():
    owners: dict[str, int] = {}
    a, b = Client(owners=owners, conn_id=1), Client(owners=owners, conn_id=2)
    assert a.send("I", b"input_int_register_0") == [("I", b"\x01INT32")]
    assert b.send("I", b"input_double_register_0,input_int_register_0") == [("I", b"\x00DOUBLE,IN_USE")]
    assert b.complaints == ["rtde#2: input setup refused: {'input_int_register_0': 'IN_USE'}"]
    assert b.send("I", b"input_double_register_0") == [("I", b"\x01DOUBLE")]
    assert owners == {"input_int_register_0": 1, "input_double_register_0": 2}
    a.conn.release()
    assert owners == {"input_double_register_0": 2}
    assert a.conn.closed is True and a.sock.closed is True
    assert b.send("I", b"input_int_register_0") == [("I", b"\x02INT32")]


def test_a_connection_takes_at_most_255_input_recipes():
    """Input recipe ids are one byte and 0 means refused."""
    c = Client()
    for i in range(1, 256):
        assert c.send("I", b"input_int_register_0") == [("I", bytes([i]) + b"INT32")]
    (kind, text), answer = c.send("I", b"input_int_register_0")
    assert kind == "M" and v1_text(text) == (1, "input setup refused: 255 input recipes already set up")
    assert answer == ("I", b"\x00INT32")
    assert len(c.conn.inputs) == 255


# The largest input recipe: 1365 VECTOR6D (65520 bytes) + DOUBLE + 3 UINT8 = 65531 bytes, with the id 65532.
BIG_INPUTS = ["external_force_torque"] * 1365 + [
    "input_double_register_0",
    "standard_digital_output",
    "standard_digital_output_mask",
    "tool_digital_output",
]


def test_an_input_recipe_whose_data_package_is_65535_bytes_is_taken_and_one_byte_more_is_refused():
    c = Client()
    [(kind, answer)] = c.send("I", ",".join(BIG_INPUTS).encode())
    assert kind == "I" and answer == b"\x01" + b"VECTOR6D," * 1365 + b"DOUBLE,UINT8,UINT8,UINT8"
    (kind, text), (akind, answer) = c.send("I", ",".join([*BIG_INPUTS, "tool_digital_output_mask"]).encode())
    reason = "input recipe of 1370 variables: its data package would not fit one package"
    assert kind == "M" and v1_text(text) == (1, reason)
    assert akind == "I" and answer == b"\x00" + b"VECTOR6D," * 1365 + b"DOUBLE,UINT8,UINT8,UINT8,UINT8"
    assert sorted(c.conn.inputs) == [1]
    fields = b"".join([struct.pack(">6d", *[float(i)] * 6) for i in range(1365)]) + struct.pack(">dBBB", 2.5, 1, 2, 3)
    assert c.send("U", b"\x01" + fields, t_s=1.0) == []
    assert c.regs.input_double[0] == 2.5 and c.regs.other_inputs["tool_digital_output"] == 3
    assert c.regs.other_inputs["external_force_torque"] == (1364.0,) * 6


# ---------------------------------------------------------------------------------------------- input packages
INPUT_NAMES = b"input_int_register_3,input_double_register_5,input_bit_registers0_to_31,external_force_torque,speed_slider_mask,standard_digital_output"


def _input_fields() -> bytes:
    return (
        struct.pack(">i", -42)
        + struct.pack(">d", 0.125)
        + struct.pack(">I", 0x80000001)
        + struct.pack(">dddddd", 1.0, 2.0, 3.0, 4.0, 5.0, 6.0)
        + struct.pack(">I", 1)
        + b"\x81"
    )


def test_an_input_package_writes_its_fields_to_the_registers_before_start():
    """RTDEIOInterface never STARTs: its packages must be taken on an idle connection."""
    c = Client()
    assert c.send("I", INPUT_NAMES) == [("I", b"\x01INT32,DOUBLE,UINT32,VECTOR6D,UINT32,UINT8")]
    assert c.send("U", b"\x01" + _input_fields(), t_s=2.5) == []
    assert c.regs.input_int[3] == -42 and c.regs.input_write_t_s[3] == 2.5
    assert c.regs.input_double[5] == 0.125
    assert c.regs.other_inputs == {
        "input_bit_registers0_to_31": 0x80000001,
        "external_force_torque": (1.0, 2.0, 3.0, 4.0, 5.0, 6.0),
        "speed_slider_mask": 1,
        "standard_digital_output": 0x81,
    }
    assert c.regs.packages == 1 and c.regs.last_package_t_s == 2.5
    assert c.regs.last_package_names == tuple(INPUT_NAMES.decode().split(","))
    assert c.input_times == [2.5]
    assert c.send("U", b"\x01" + _input_fields(), t_s=2.75) == []
    assert c.regs.packages == 2 and c.regs.last_package_t_s == 2.75 and c.input_times == [2.5, 2.75]
    assert c.complaints == [] and c.conn.started is False


def test_each_input_recipe_writes_only_its_own_fields():
    c = Client()
    c.send("I", b"input_int_register_0")
    c.send("I", b"input_int_register_1,input_double_register_0")
    c.send("U", b"\x02" + struct.pack(">id", 5, -1.5), t_s=1.0)
    assert c.regs.input_int[:2] == [0, 5] and c.regs.input_double[0] == -1.5
    assert c.regs.input_write_t_s[:2] == [-1.0, 1.0]
    assert c.regs.last_package_names == ("input_int_register_1", "input_double_register_0")


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"", "data package for unknown input recipe (none)"),
        (b"\x09" + struct.pack(">i", 1), "data package for unknown input recipe 09"),
        (b"\x00", "data package for unknown input recipe 00"),
        (b"\x01\x00\x00\x00", "recipe 1 package of 4 bytes, expected 5"),
        (b"\x01\x00\x00\x00\x00\x00", "recipe 1 package of 6 bytes, expected 5"),
    ],
)
def test_an_input_package_for_no_recipe_or_of_the_wrong_size_is_refused_and_changes_nothing(payload, reason):
    c = Client()
    c.send("I", b"input_int_register_0")
    (kind, text), *rest = c.send("U", payload, t_s=1.0)
    assert kind == "M" and v1_text(text) == (1, reason) and rest == []
    assert c.regs.input_int[0] == 0 and c.regs.packages == 0 and c.regs.last_package_t_s == -1.0
    assert c.input_times == []
    assert c.complaints == [f"rtde#7: {reason}"]


# ---------------------------------------------------------------------------------------------- text messages
def test_refusals_are_version_1_text_messages_until_version_2_is_negotiated():
    c = Client()
    [(kind, text)] = c.send("Z")
    assert kind == "M" and text == b"\x01unknown package type 90"
    c.negotiate(2)
    [(kind, text)] = c.send("Z")
    assert kind == "M" and text == b"\x17unknown package type 90\x04RTDE\x01"
    c.negotiate(1)
    assert c.send("z") == [("M", b"\x01unknown package type 122")]


def test_a_text_message_from_the_client_is_logged_cut_to_200_bytes_and_not_answered():
    c = Client()
    assert c.send("M", b"\x03hello") == []
    assert c.send("M", b"a" * 199 + b"bc") == []
    assert c.complaints == ["rtde#7: client message b'\\x03hello'", f"rtde#7: client message b'{'a' * 199}b'"]


# ---------------------------------------------------------------------------------------------- framing
def test_packages_split_anywhere_or_run_together_are_answered_in_order():
    stream = package("V", b"\x00\x02") + package("v") + package("O", v2_outputs(25.0, "timestamp")) + package("S")
    expected = [
        ("V", b"\x01"),
        ("v", bytes.fromhex("00000003 0000000f 00000007 00019f5b")),
        ("O", b"\x01DOUBLE"),
        ("S", b"\x01"),
    ]
    assert Client().feed(stream) == expected
    c = Client()
    out = [p for i in range(len(stream)) for p in c.feed(stream[i : i + 1])]
    assert out == expected


@pytest.mark.parametrize("size", [0, 1, 2])
def test_a_size_below_the_header_loses_the_framing_the_client_is_told_and_receive_raises(size):
    c = Client()
    with pytest.raises(ValueError, match=rf"^RTDE package with impossible size {size}$"):
        c.conn.receive(struct.pack(">HB", size, ord("U")) + b"junk", 1.0)
    reason = f"RTDE package with impossible size {size}; closing"
    assert c.replies() == [("M", b"\x01" + reason.encode())]
    assert c.complaints == [f"rtde#7: {reason}"]


def test_packages_before_a_lost_framing_in_the_same_chunk_are_still_handled():
    """The stream is read package by package: what came complete before the broken header is answered or applied
    (an input package included), then the client is told and ``receive`` raises."""
    c = Client()
    c.send("I", b"input_int_register_0")
    chunk = package("V", b"\x00\x02") + package("U", b"\x01" + struct.pack(">i", 77)) + b"\x00\x02U" + b"junk"
    with pytest.raises(ValueError, match=r"^RTDE package with impossible size 2$"):
        c.conn.receive(chunk, 1.0)
    [(k1, answer), (k2, text)] = c.replies()
    assert (k1, answer) == ("V", b"\x01") and k2 == "M"
    assert v2_text(text) == ("RTDE package with impossible size 2; closing", "RTDE", 1)
    assert c.regs.input_int[0] == 77 and c.input_times == [1.0]


def test_a_lost_framing_after_a_version_2_negotiation_is_told_in_version_2():
    c = Client()
    c.negotiate(2)
    with pytest.raises(ValueError):
        c.conn.receive(b"\x00\x01U", 1.0)
    [(kind, text)] = c.replies()
    assert kind == "M" and v2_text(text) == ("RTDE package with impossible size 1; closing", "RTDE", 1)


# ---------------------------------------------------------------------------------------------- sending
def test_delayed_bytes_leave_at_their_release_time_in_order_and_the_rest_at_once():
    c = Client()
    c.conn.send(b"first", release_t_s=1.0)
    c.conn.send(b"second", release_t_s=2.0)
    c.conn.send(b"now")
    assert c.conn.flush(0.5) is True and c.sock.sent == b"now"
    assert c.conn.flush(1.0) is True and c.sock.sent == b"nowfirst"  # due exactly at its release time
    assert c.conn.flush(1.999) is True and c.sock.sent == b"nowfirst"
    assert c.conn.flush(5.0) is True and c.sock.sent == b"nowfirstsecond"
    assert len(c.conn.delayed) == 0


def test_what_the_socket_does_not_take_waits_for_the_next_flush():
    c = Client()
    c.sock.accept = 3
    c.conn.send(b"abcdefg")
    assert c.conn.flush(0.0) is True and c.sock.sent == b"abc"
    assert c.conn.flush(0.0) is True and c.sock.sent == b"abcdef"
    assert c.conn.flush(0.0) is True and c.sock.sent == b"abcdefg"


def test_a_client_that_lets_one_mebibyte_pile_up_is_to_be_closed():
    """MAX_BACKLOG_BYTES = 2**20: one byte under is kept, at the limit ``flush`` says close."""
    c = Client()
    c.sock.send_error = BlockingIOError()
    c.conn.send(b"\x00" * ((1 << 20) - 1))
    assert c.conn.flush(0.0) is True
    c.conn.send(b"\x00")
    assert c.conn.flush(0.0) is False
    c.sock.send_error = None
    assert c.conn.flush(0.0) is True and len(c.sock.sent) == 1 << 20


def test_a_socket_error_says_close():
    c = Client()
    c.sock.send_error = ConnectionResetError()
    c.conn.send(b"x")
    assert c.conn.flush(0.0) is False


def test_release_survives_a_socket_that_fails_to_close():
    owners = {"input_int_register_5": 9}
    c = Client(owners=owners)
    c.send("I", b"input_int_register_0")
    c.sock.close_error = OSError("already gone")
    c.conn.release()
    assert c.sock.closed is True and c.conn.closed is True
    assert owners == {"input_int_register_5": 9}
