"""RTDE wire format (protocol versions 1 and 2) as a UR controller serves it on TCP 30004.

Every package: ``uint16 size`` (including the 3-byte header), ``uint8 type``, payload; big-endian.
Types and sizes follow UR's RTDE guide; ``ur_rtde`` decodes data packages with its own table, so the
types here must be the guide's exactly. Where the versions differ (UR's RTDE guide, the package tables; read
the same way by UR's Client Library, ``src/rtde/*.cpp``, and UR's Python client, ``rtde/serialize.py``): a
version 1 output setup carries no frequency and its answer no recipe id, a version 1 output data package no recipe
id, and a version 1 text message is ``uint8 level`` then the message, where version 2 has ``uint8`` length-prefixed
message and source, then ``uint8 level``.
"""

from __future__ import annotations

import struct

HEADER = struct.Struct(">HB")
REQUEST_PROTOCOL_VERSION = ord("V")
GET_URCONTROL_VERSION = ord("v")
TEXT_MESSAGE = ord("M")
DATA_PACKAGE = ord("U")
SETUP_OUTPUTS = ord("O")
SETUP_INPUTS = ord("I")
START = ord("S")
PAUSE = ord("P")

NOT_FOUND = "NOT_FOUND"
IN_USE = "IN_USE"
PROTOCOL_VERSIONS = (1, 2)
"""The versions a CB3 (PolyScope 3.15) accepts in ``REQUEST_PROTOCOL_VERSION``; a client that asks for none
speaks version 1 (UR's Client Library sets its parser to version 1 before negotiating)."""
MAX_PACKAGE_BYTES = 0xFFFF
"""The ``uint16`` size field's limit (header included)."""
EXCEPTION_MESSAGE, ERROR_MESSAGE, WARNING_MESSAGE, INFO_MESSAGE = 0, 1, 2, 3
"""``TEXT_MESSAGE`` levels (UR's RTDE guide, "RTDE_TEXT_MESSAGE")."""

TYPE_FORMATS = {
    "BOOL": "?",
    "UINT8": "B",
    "UINT32": "I",
    "INT32": "i",
    "UINT64": "Q",
    "DOUBLE": "d",
    "VECTOR3D": "3d",
    "VECTOR6D": "6d",
    "VECTOR6INT32": "6i",
    "VECTOR6UINT32": "6I",
}
"""RTDE type name -> struct format."""
TYPE_WIDTHS = {"VECTOR3D": 3, "VECTOR6D": 6, "VECTOR6INT32": 6, "VECTOR6UINT32": 6}
"""Number of values of the vector types (the others hold one)."""

_V6 = "VECTOR6D"
OUTPUT_TYPES: dict[str, str] = {
    "timestamp": "DOUBLE",
    **{n: _V6 for n in ("target_q", "target_qd", "target_qdd", "target_current", "target_moment")},
    **{n: _V6 for n in ("actual_q", "actual_qd", "actual_current", "joint_control_output")},
    **{n: _V6 for n in ("actual_TCP_pose", "actual_TCP_speed", "actual_TCP_force")},
    **{n: _V6 for n in ("target_TCP_pose", "target_TCP_speed", "joint_temperatures", "actual_joint_voltage")},
    "tcp_offset": _V6,
    "actual_digital_input_bits": "UINT64",
    "actual_execution_time": "DOUBLE",
    "robot_mode": "INT32",
    "joint_mode": "VECTOR6INT32",
    "safety_mode": "INT32",
    "safety_status": "INT32",
    "actual_tool_accelerometer": "VECTOR3D",
    "speed_scaling": "DOUBLE",
    "target_speed_fraction": "DOUBLE",
    "actual_momentum": "DOUBLE",
    "actual_main_voltage": "DOUBLE",
    "actual_robot_voltage": "DOUBLE",
    "actual_robot_current": "DOUBLE",
    "actual_digital_output_bits": "UINT64",
    "runtime_state": "UINT32",
    "joint_position_deviation_ratio": "DOUBLE",
    "elbow_position": "VECTOR3D",
    "elbow_velocity": "VECTOR3D",
    "robot_status_bits": "UINT32",
    "safety_status_bits": "UINT32",
    "analog_io_types": "UINT32",
    "standard_analog_input0": "DOUBLE",
    "standard_analog_input1": "DOUBLE",
    "standard_analog_output0": "DOUBLE",
    "standard_analog_output1": "DOUBLE",
    "io_current": "DOUBLE",
    "tool_mode": "UINT32",
    "tool_analog_input_types": "UINT32",
    "tool_analog_input0": "DOUBLE",
    "tool_analog_input1": "DOUBLE",
    "tool_output_voltage": "INT32",
    "tool_output_current": "DOUBLE",
    "tool_temperature": "DOUBLE",
    "tcp_force_scalar": "DOUBLE",
    "output_bit_registers0_to_31": "UINT32",
    "output_bit_registers32_to_63": "UINT32",
    "payload": "DOUBLE",
    "payload_cog": "VECTOR3D",
    "payload_inertia": "VECTOR6D",
    **{f"output_int_register_{i}": "INT32" for i in range(48)},
    **{f"output_double_register_{i}": "DOUBLE" for i in range(48)},
    **{f"input_int_register_{i}": "INT32" for i in range(48)},
    **{f"input_double_register_{i}": "DOUBLE" for i in range(48)},
}
"""Outputs a CB3 (PolyScope 3.15) serves. Names only e-Series serve (``ft_raw_wrench``, ...) are NOT_FOUND.
``safety_status`` and ``joint_position_deviation_ratio`` are served because UR's RTDE client asks for them in its
default recipe (``examples/record_configuration.xml``); whether a CB3 3.15 serves them is not checked."""

NOT_EMULATED = (
    "target_qdd",
    "target_current",
    "target_moment",
    "actual_current",
    "joint_control_output",
    "joint_temperatures",
    "actual_execution_time",
    "actual_tool_accelerometer",
    "actual_momentum",
    "actual_main_voltage",
    "actual_robot_voltage",
    "actual_robot_current",
    "actual_joint_voltage",
    "elbow_position",
    "elbow_velocity",
    "standard_analog_input0",
    "standard_analog_input1",
    "standard_analog_output0",
    "standard_analog_output1",
    "io_current",
    "tool_analog_input0",
    "tool_analog_input1",
    "tool_output_current",
    "tool_temperature",
    "actual_digital_input_bits",
    "joint_position_deviation_ratio",
)
"""Outputs served with constant values: an RTDE setup that asks for them is logged as such."""

INPUT_TYPES: dict[str, str] = {
    **{f"input_int_register_{i}": "INT32" for i in range(48)},
    **{f"input_double_register_{i}": "DOUBLE" for i in range(48)},
    "input_bit_registers0_to_31": "UINT32",
    "input_bit_registers32_to_63": "UINT32",
    "standard_digital_output_mask": "UINT8",
    "standard_digital_output": "UINT8",
    "configurable_digital_output_mask": "UINT8",
    "configurable_digital_output": "UINT8",
    "tool_digital_output_mask": "UINT8",
    "tool_digital_output": "UINT8",
    "standard_analog_output_mask": "UINT8",
    "standard_analog_output_type": "UINT8",
    "standard_analog_output_0": "DOUBLE",
    "standard_analog_output_1": "DOUBLE",
    "speed_slider_mask": "UINT32",
    "speed_slider_fraction": "DOUBLE",
    "external_force_torque": "VECTOR6D",
}
"""Inputs a CB3 accepts."""


def pack(kind: int, payload: bytes = b"") -> bytes:
    """One RTDE package; ``ValueError`` if it would not fit the size field (:data:`MAX_PACKAGE_BYTES`)."""
    if HEADER.size + len(payload) > MAX_PACKAGE_BYTES:
        raise ValueError(f"RTDE package of {HEADER.size + len(payload)} bytes, more than {MAX_PACKAGE_BYTES}")
    return HEADER.pack(HEADER.size + len(payload), kind) + payload


def text_message(message: str, level: int, protocol_version: int, source: str = "RTDE") -> bytes:
    """A ``TEXT_MESSAGE`` package in the given protocol version's layout (message and source cut to 255 bytes)."""
    text = message.encode(errors="replace")[:255]
    if protocol_version == 1:
        return pack(TEXT_MESSAGE, bytes([level]) + text)
    src = source.encode(errors="replace")[:255]
    return pack(TEXT_MESSAGE, bytes([len(text)]) + text + bytes([len(src)]) + src + bytes([level]))


def recipe_struct(types: list[str], recipe_id: bool = True) -> struct.Struct:
    """Struct of a data package of a recipe: the recipe id byte (not in version 1 outputs), then the fields in order."""
    return struct.Struct((">B" if recipe_id else ">") + "".join(TYPE_FORMATS[t] for t in types))


def flatten(values: list, types: list[str]) -> list:
    """Values of a recipe flattened for :func:`recipe_struct` (vectors spread out)."""
    out: list = []
    for v, t in zip(values, types, strict=True):
        if t in TYPE_WIDTHS:
            out.extend(v)
        else:
            out.append(v)
    return out


def unflatten(flat: tuple, types: list[str]) -> list:
    """Inverse of :func:`flatten`: one value (or tuple for vectors) per field."""
    out: list = []
    i = 0
    for t in types:
        n = TYPE_WIDTHS.get(t, 0)
        if n:
            out.append(tuple(flat[i : i + n]))
            i += n
        else:
            out.append(flat[i])
            i += 1
    return out


class FramingError(ValueError):
    """A size field below the header's 3 bytes: the stream's framing is lost.

    Attributes:
        packages: the complete packages ``(type, payload)`` that came before the broken header in the same feed.
    """

    def __init__(self, message: str, packages: list[tuple[int, bytes]]) -> None:
        super().__init__(message)
        self.packages = packages


class PackageReader:
    """Reassembles RTDE packages from a TCP byte stream."""

    def __init__(self) -> None:
        self.buffer = bytearray()

    def feed(self, data: bytes) -> list[tuple[int, bytes]]:
        """Append received bytes; return the complete packages ``(type, payload)``.

        :class:`FramingError` (a ``ValueError``) at a size field below 3, carrying the packages before it.
        """
        self.buffer.extend(data)
        out: list[tuple[int, bytes]] = []
        while len(self.buffer) >= HEADER.size:
            size, kind = HEADER.unpack_from(self.buffer)
            if size < HEADER.size:
                raise FramingError(f"RTDE package with impossible size {size}", out)
            if len(self.buffer) < size:
                break
            out.append((kind, bytes(self.buffer[HEADER.size : size])))
            del self.buffer[:size]
        return out
