"""The emulator's RTDE wire format (``envs/real/emulator/rtde_protocol.py``) against bytes written out by hand.

Oracle: UR's RTDE guide ("Real-Time Data Exchange (RTDE) Guide"), its package tables. Every package is ``uint16``
size (the 3-byte header included), ``uint8`` type, payload, big-endian. Field types: BOOL (8 bits, 0 or 1),
UINT8, UINT32, UINT64, INT32, DOUBLE (IEEE 754, 64 bits), VECTOR3D (3 DOUBLE), VECTOR6D (6 DOUBLE), VECTOR6INT32,
VECTOR6UINT32. RTDE_TEXT_MESSAGE: version 2 ``uint8`` message length, message, ``uint8`` source length, source,
``uint8`` warning level (EXCEPTION 0, ERROR 1, WARNING 2, INFO 3); version 1 ``uint8`` message type, message.
The expected bytes are spelled out here with :mod:`struct` formats of the guide's types, never with the module's
own tables or helpers; no test waits or opens a socket.
"""

from __future__ import annotations

import struct

import pytest

from drillgym.envs.real.emulator import rtde_protocol as rp


def test_a_package_is_size_type_payload_big_endian():
    assert rp.pack(ord("S")) == b"\x00\x03S"
    assert rp.pack(ord("V"), b"\x00\x02") == b"\x00\x05V\x00\x02"
    assert rp.pack(0x55, b"x" * 300) == b"\x01\x2fU" + b"x" * 300


def test_the_largest_package_fits_the_uint16_size_field_and_one_byte_more_is_refused():
    largest = rp.pack(ord("U"), b"\xaa" * 65532)
    assert largest[:3] == b"\xff\xffU" and len(largest) == 65535
    with pytest.raises(ValueError, match=r"^RTDE package of 65536 bytes, more than 65535$"):
        rp.pack(ord("U"), b"\xaa" * 65533)


def test_version_1_text_message_is_level_then_message():
    assert rp.text_message("boom", 1, 1) == b"\x00\x08M\x01boom"
    assert rp.text_message("careful", 2, 1, source="ignored in v1") == b"\x00\x0bM\x02careful"


def test_version_2_text_message_is_length_prefixed_message_and_source_then_level():
    assert rp.text_message("boom", 0, 2) == b"\x00\x0eM\x04boom\x04RTDE\x00"
    assert rp.text_message("hi", 3, 2, source="ctl") == b"\x00\x0bM\x02hi\x03ctl\x03"
    assert rp.text_message("", 1, 2, source="") == b"\x00\x06M\x00\x00\x01"


def test_text_message_cuts_message_and_source_to_255_bytes():
    """A uint8 length field holds at most 255: the message and the source are cut there."""
    long_message, long_source = "m" * 300, "s" * 260
    v1 = rp.text_message(long_message, 2, 1)
    assert v1 == struct.pack(">HB", 3 + 1 + 255, ord("M")) + b"\x02" + b"m" * 255
    v2 = rp.text_message(long_message, 2, 2, source=long_source)
    assert (
        v2
        == struct.pack(">HB", 3 + 1 + 255 + 1 + 255 + 1, ord("M"))
        + b"\xff"
        + b"m" * 255
        + b"\xff"
        + b"s" * 255
        + b"\x02"
    )
    assert rp.text_message("m" * 255, 2, 1) == v1  # exactly 255 is kept whole


def test_text_message_replaces_what_cannot_be_encoded():
    """A lone surrogate (not encodable in UTF-8) becomes ``?`` in the message and the source alike."""
    assert rp.text_message("a\udc80b", 1, 1) == b"\x00\x07M\x01a?b"
    assert rp.text_message("x", 1, 2, source="s\udc80") == b"\x00\x09M\x01x\x02s?\x01"


@pytest.mark.parametrize(
    ("rtde_type", "value", "wire"),
    [
        ("BOOL", True, b"\x01"),
        ("BOOL", False, b"\x00"),
        ("UINT8", 200, b"\xc8"),
        ("UINT32", 0xDEADBEEF, b"\xde\xad\xbe\xef"),
        ("INT32", -2, b"\xff\xff\xff\xfe"),
        ("UINT64", 0x0102030405060708, b"\x01\x02\x03\x04\x05\x06\x07\x08"),
        ("DOUBLE", 1.5, b"\x3f\xf8" + b"\x00" * 6),
        ("VECTOR3D", (1.0, -2.0, 0.5), bytes.fromhex("3ff0000000000000 c000000000000000 3fe0000000000000")),
        ("VECTOR6D", (0.0, 0.0, 0.0, 0.0, 0.0, 2.0), b"\x00" * 40 + b"\x40" + b"\x00" * 7),
        ("VECTOR6INT32", (1, -1, 2, -2, 3, 0), bytes.fromhex("00000001 ffffffff 00000002 fffffffe 00000003 00000000")),
        (
            "VECTOR6UINT32",
            (1, 2, 3, 4, 5, 0xFFFFFFFF),
            bytes.fromhex("00000001 00000002 00000003 00000004 00000005 ffffffff"),
        ),
    ],
)
def test_each_type_packs_to_the_guides_layout_with_and_without_recipe_id(rtde_type, value, wire):
    st = rp.recipe_struct([rtde_type])
    flat = rp.flatten([value], [rtde_type])
    assert st.pack(7, *flat) == b"\x07" + wire
    assert rp.recipe_struct([rtde_type], recipe_id=False).pack(*flat) == wire
    assert rp.unflatten(st.unpack(b"\x07" + wire)[1:], [rtde_type]) == [value]


def test_a_recipe_packs_its_fields_in_order_without_padding():
    types = ["UINT8", "DOUBLE", "VECTOR3D", "BOOL", "VECTOR6INT32", "UINT64"]
    values = [3, -1.0, (0.0, 1.0, 2.0), True, (1, 2, 3, 4, 5, 6), 9]
    st = rp.recipe_struct(types)
    expected = (
        b"\x01"
        + b"\x03"
        + struct.pack(">d", -1.0)
        + struct.pack(">ddd", 0.0, 1.0, 2.0)
        + b"\x01"
        + struct.pack(">iiiiii", 1, 2, 3, 4, 5, 6)
        + struct.pack(">Q", 9)
    )
    assert st.size == 1 + 1 + 8 + 24 + 1 + 24 + 8
    assert st.pack(1, *rp.flatten(values, types)) == expected
    assert rp.flatten(values, types) == [3, -1.0, 0.0, 1.0, 2.0, True, 1, 2, 3, 4, 5, 6, 9]
    assert rp.unflatten(st.unpack(expected)[1:], types) == values
    assert rp.recipe_struct([]).pack(4) == b"\x04" and rp.recipe_struct([], recipe_id=False).size == 0


def test_the_recipe_id_is_a_uint8_up_to_255():
    """The guide's recipe id is ``uint8``: ids 128-255 (input recipes go up to 255) pack and read unsigned."""
    st = rp.recipe_struct(["UINT8"])
    assert st.pack(200, 1) == b"\xc8\x01" and st.pack(255, 0) == b"\xff\x00"
    assert st.unpack(b"\xc8\x01") == (200, 1)


def test_unflatten_gives_tuples_for_vectors_and_scalars_for_the_rest():
    flat = (1, 2.0, 3.0, 4.0, 5, 6, 7, 8, 9, 10, 11)
    out = rp.unflatten(flat, ["INT32", "VECTOR3D", "VECTOR6UINT32", "UINT32"])
    assert out == [1, (2.0, 3.0, 4.0), (5, 6, 7, 8, 9, 10), 11]
    assert type(out[0]) is int and type(out[1]) is tuple and type(out[3]) is int


def test_flatten_refuses_values_and_types_of_different_lengths():
    """A recipe with a value missing or one too many is a caller's bug, not a package to pack short."""
    with pytest.raises(ValueError):
        rp.flatten([1.0], ["DOUBLE", "DOUBLE"])
    with pytest.raises(ValueError):
        rp.flatten([1.0, 2.0], ["DOUBLE"])


def _package(kind: str, payload: bytes = b"") -> bytes:
    return struct.pack(">HB", 3 + len(payload), ord(kind)) + payload


def test_the_reader_reassembles_packages_split_anywhere():
    stream = _package("V", b"\x00\x02") + _package("S") + _package("O", b"timestamp")
    for cut in range(len(stream) + 1):
        reader = rp.PackageReader()
        out = reader.feed(stream[:cut]) + reader.feed(stream[cut:])
        assert out == [(ord("V"), b"\x00\x02"), (ord("S"), b""), (ord("O"), b"timestamp")], cut
        assert reader.buffer == b""
    reader = rp.PackageReader()
    out = [p for i in range(len(stream)) for p in reader.feed(stream[i : i + 1])]
    assert [k for k, _ in out] == [ord("V"), ord("S"), ord("O")]


def test_the_reader_returns_a_header_only_package_as_soon_as_its_three_bytes_are_in():
    reader = rp.PackageReader()
    assert reader.feed(b"\x00\x03") == []
    assert reader.feed(b"P") == [(ord("P"), b"")]
    assert reader.feed(b"\x00\x04U") == [] and reader.buffer == b"\x00\x04U"
    assert reader.feed(b"\x09") == [(ord("U"), b"\x09")]


@pytest.mark.parametrize("size", [0, 1, 2])
def test_the_reader_refuses_a_size_below_the_header(size):
    """A size below 3 cannot be a package: the stream's framing is lost."""
    reader = rp.PackageReader()
    with pytest.raises(ValueError, match=rf"^RTDE package with impossible size {size}$"):
        reader.feed(struct.pack(">HB", size, ord("U")) + b"rest")


def test_a_lost_framing_carries_the_packages_complete_before_it():
    """The reader that finds a broken header still hands over what came whole before it, in order."""
    reader = rp.PackageReader()
    with pytest.raises(rp.FramingError, match=r"^RTDE package with impossible size 1$") as lost:
        reader.feed(_package("V", b"\x00\x02") + _package("S") + b"\x00\x01S" + _package("P"))
    assert lost.value.packages == [(ord("V"), b"\x00\x02"), (ord("S"), b"")]
    assert isinstance(lost.value, ValueError)
