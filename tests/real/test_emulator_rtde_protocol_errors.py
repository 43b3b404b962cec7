"""RTDE clients that speak protocol version 1, or break the protocol, are answered and never end the emulator.

Sources. UR's RTDE guide ("Real-Time Data Exchange (RTDE) Guide"), its package tables: RTDE_REQUEST_PROTOCOL_VERSION
(``uint16`` version in, ``uint8`` accepted out), RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS (version 2: ``double`` output
frequency then the variable names, answered with the output recipe id and the types; version 1: the names only,
answered with the types only), RTDE_DATA_PACKAGE, RTDE_TEXT_MESSAGE (version 2: ``uint8`` message length, message,
``uint8`` source length, source, ``uint8`` warning level, EXCEPTION 0, ERROR 1, WARNING 2, INFO 3; version 1:
``uint8`` message type, then the message). The same layouts as UR's Client Library reads them
(``src/rtde/control_package_setup_outputs.cpp``, ``data_package.cpp``: no recipe id in a version 1 output data
package; ``text_message.cpp``) and UR's Python client (``rtde/serialize.py``, ``MessageV1`` and ``Message``). A CB3
(PolyScope 3.15) accepts versions 1 and 2; a client that negotiates nothing speaks version 1 (UR's Client Library
sets its parser to version 1 before negotiating). Which malformed requests get a text message, and its text, are
the emulator's choice (docs/deployment.md §6), not checked against a controller.

Issue 43's bug: an RTDE SETUP_OUTPUTS with a payload shorter than 8 bytes (a version 1 client's) ended the whole
emulator with an uncaught exception.
"""

from __future__ import annotations

import itertools
import socket
import struct

import pytest
import rtde_receive

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.emulator.config import RTDE_PORT
from drillgym.envs.real.emulator.process import EmulatorProcess, ports_free
from drillgym.envs.real.emulator.rtde_server import CONTROLLER_VERSION


class RawRtde:
    """A raw RTDE connection that sends packages and reads the answers, keeping the text messages apart."""

    def __init__(self, host: str) -> None:
        self.sock = socket.create_connection((host, RTDE_PORT), timeout=3.0)
        self.reader = rp.PackageReader()
        self.pending: list[tuple[int, bytes]] = []
        self.messages: list[bytes] = []

    def send(self, kind: int, payload: bytes = b"") -> None:
        self.sock.sendall(rp.pack(kind, payload))

    def next(self) -> tuple[int, bytes]:
        """The next package (``OSError`` if the emulator closes the connection first)."""
        while not self.pending:
            data = self.sock.recv(65536)
            if not data:
                raise OSError("closed by the emulator")
            self.pending += self.reader.feed(data)
        return self.pending.pop(0)

    def answer(self, kind: int) -> bytes:
        """The payload of the next package of type ``kind``; text messages before it are kept in ``messages``."""
        while True:
            k, payload = self.next()
            if k == kind:
                return payload
            assert k == rp.TEXT_MESSAGE, f"package {chr(k)!r} while waiting for {chr(kind)!r}"
            self.messages.append(payload)

    def request(self, kind: int, payload: bytes = b"") -> bytes:
        self.send(kind, payload)
        return self.answer(kind)

    def close(self) -> None:
        self.sock.close()


def _v2_message(payload: bytes) -> tuple[str, str, int]:
    """(message, source, level) of a version 2 TEXT_MESSAGE, checking that its lengths add up."""
    n = payload[0]
    message = payload[1 : 1 + n].decode()
    m = payload[1 + n]
    source = payload[2 + n : 2 + n + m].decode()
    assert len(payload) == 3 + n + m, "length fields and payload disagree"
    return message, source, payload[-1]


@pytest.fixture(scope="module")
def shared_emulator():
    """One emulator for the module (each test opens its own connections); at the end it still serves ``ur_rtde``,
    and it exits cleanly."""
    emu = EmulatorProcess(max_lifetime_s=300.0).start()
    yield emu
    r = rtde_receive.RTDEReceiveInterface(emu.host, 125.0, ["timestamp"])
    try:
        assert r.isConnected() and r.getTimestamp() > 0.0
    finally:
        r.disconnect()
    assert emu.stop() == 0, emu.log_tail()
    assert ports_free(emu.host)


@pytest.fixture
def emulator(shared_emulator):
    """The shared emulator, checked after each test: still running, and a new RTDE client is answered."""
    yield shared_emulator
    assert shared_emulator.proc.poll() is None, f"the emulator ended: {shared_emulator.log_tail()}"
    probe = RawRtde(shared_emulator.host)
    try:
        assert probe.request(rp.GET_URCONTROL_VERSION) == struct.pack(">IIII", *CONTROLLER_VERSION)
    finally:
        probe.close()


def test_a_version_1_output_setup_without_negotiation_is_read_as_version_1(emulator):
    """Issue 43's crash: a 2-byte SETUP_OUTPUTS. Without a negotiation the client speaks version 1: names only."""
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.SETUP_OUTPUTS, b"ts") == rp.NOT_FOUND.encode()  # version 1: types only, no recipe id
        assert c.request(rp.SETUP_OUTPUTS, b"timestamp,actual_q") == b"DOUBLE,VECTOR6D"
    finally:
        c.close()


def test_a_version_1_client_is_accepted_and_streamed_without_recipe_ids_at_125_hz(emulator):
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 1)) == b"\x01"
        assert c.request(rp.SETUP_OUTPUTS, b"timestamp,robot_mode") == b"DOUBLE,INT32"
        assert c.request(rp.START) == b"\x01"
        stamps = []
        for _ in range(4):
            payload = c.answer(rp.DATA_PACKAGE)
            assert len(payload) == 12, "version 1 data package: the fields only, no recipe id byte"
            stamps.append(struct.unpack(">di", payload)[0])
        steps = [round((b - a) / 0.008) for a, b in itertools.pairwise(stamps)]
        assert steps == [1, 1, 1], stamps  # one package per 8 ms cycle (cycles run late are caught up, each sent)
        assert c.messages == []
    finally:
        c.close()


@pytest.mark.parametrize("version", [0, 3, 65535])
def test_protocol_versions_a_cb3_does_not_speak_are_refused_and_the_version_stays(emulator, version):
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", version)) == b"\x00"
        answer = c.request(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"timestamp")
        assert answer == b"\x01DOUBLE"  # still version 2: recipe id, then types
        assert c.messages == []  # a refusal is an answer, not an error
    finally:
        c.close()


def test_a_short_version_2_output_setup_gets_an_error_message_and_a_refusal(emulator):
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        assert c.request(rp.SETUP_OUTPUTS, b"ts") == b"\x00"  # recipe id 0: refused, no types
        [message] = c.messages
        text, source, level = _v2_message(message)
        assert level == rp.ERROR_MESSAGE and source == "RTDE" and "8-byte output frequency" in text
        assert c.request(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"timestamp") == b"\x01DOUBLE"  # goes on
    finally:
        c.close()


def test_a_version_1_connection_gets_its_error_messages_in_the_version_1_layout(emulator):
    c = RawRtde(emulator.host)
    try:
        c.send(ord("Z"))  # no such package type
        k, payload = c.next()
        assert k == rp.TEXT_MESSAGE and payload[0] == rp.ERROR_MESSAGE and b"unknown package type 90" in payload[1:]
    finally:
        c.close()


@pytest.mark.parametrize(
    ("kind", "payload", "answer", "said"),
    [
        (rp.REQUEST_PROTOCOL_VERSION, b"\x02", b"\x00", "REQUEST_PROTOCOL_VERSION"),
        (rp.REQUEST_PROTOCOL_VERSION, b"\x00\x02\x00", b"\x00", "REQUEST_PROTOCOL_VERSION"),
        (rp.SETUP_OUTPUTS, struct.pack(">d", float("nan")) + b"timestamp", b"\x00DOUBLE", "not a number"),
        (rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"actual_q," * 1400, b"\x00" + b"VECTOR6D," * 1399 + b"VECTOR6D",
         "data package would not fit"),
        (rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"a," * 20000, b"\x00", "answer would not fit"),
    ],
)  # fmt: skip
def test_malformed_requests_get_an_error_message_and_their_refusal(emulator, kind, payload, answer, said):
    """1400 ``actual_q`` (48 bytes each) make a 67 kB data package, over the 65535-byte size field; 20000 unknown
    one-letter names (2 bytes each) a 200 kB answer of ``NOT_FOUND``: both used to end the emulator."""
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        assert c.request(kind, payload) == answer
        [message] = c.messages
        assert said in _v2_message(message)[0]
    finally:
        c.close()


def test_data_packages_of_unknown_recipes_or_sizes_get_an_error_message(emulator):
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        assert c.request(rp.SETUP_INPUTS, b"input_int_register_30") == b"\x01INT32"
        c.send(rp.DATA_PACKAGE, b"\x07" + bytes(4))  # recipe 7 was never set up
        c.send(rp.DATA_PACKAGE, b"\x01" + bytes(3))  # recipe 1 is 4 bytes of INT32, not 3
        c.send(rp.DATA_PACKAGE)  # no recipe id at all
        texts = [_v2_message(c.answer(rp.TEXT_MESSAGE))[0] for _ in range(3)]
        assert "unknown input recipe 07" in texts[0] and "expected 5" in texts[1] and "(none)" in texts[2]
        c.send(rp.DATA_PACKAGE, b"\x01" + struct.pack(">i", 42))  # a good one is still taken
        assert c.request(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"input_int_register_30") == b"\x01INT32"
        assert c.request(rp.START) == b"\x01"
        assert struct.unpack(">Bi", c.answer(rp.DATA_PACKAGE)) == (1, 42)
    finally:
        c.close()


def test_the_256th_input_recipe_is_refused(emulator):
    """Recipe ids are one byte and 0 means refused: 255 input recipes per connection."""
    c = RawRtde(emulator.host)
    try:
        assert c.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        for i in range(1, 256):
            assert c.request(rp.SETUP_INPUTS, b"input_double_register_40")[0] == i
        assert c.request(rp.SETUP_INPUTS, b"input_double_register_40") == b"\x00DOUBLE"
        assert "255 input recipes" in _v2_message(c.messages[-1])[0]
    finally:
        c.close()


@pytest.mark.parametrize("size", [0, 1, 2])
def test_a_size_field_below_the_header_gets_a_message_and_closes_only_that_connection(emulator, size):
    other = RawRtde(emulator.host)
    c = RawRtde(emulator.host)
    try:
        assert other.request(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2)) == b"\x01"
        c.sock.sendall(struct.pack(">HB", size, rp.START))
        k, payload = c.next()
        assert k == rp.TEXT_MESSAGE and b"impossible size" in payload
        with pytest.raises(OSError, match="closed"):
            c.next()
        assert other.request(rp.GET_URCONTROL_VERSION)[:4] == struct.pack(">I", 3)  # the others are served on
    finally:
        c.close()
        other.close()
