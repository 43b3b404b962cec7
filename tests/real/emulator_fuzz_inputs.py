"""Hypothesis strategies of what a buggy, foreign or hostile client sends to each emulator port.

Each strategy mixes well-formed requests (so the fuzzer reaches past the first parser check), near misses (a valid
request with one field wrong: a bad size, a NaN, an unknown name, a CR), and arbitrary bytes. Sizes are small
except for a few chosen large inputs (recipes that overflow the RTDE size field, lines and programs past the
emulator's bounds), which random bytes would never reach.
"""

from __future__ import annotations

import json
import struct

from hypothesis import strategies as st

from drillgym.envs.real.emulator import rtde_protocol as rp
from drillgym.envs.real.netft import CMD_SET_SOFTWARE_BIAS, CMD_START_REALTIME, CMD_STOP


def sessions(stream: st.SearchStrategy[bytes]) -> st.SearchStrategy[list[bytes]]:
    """One to four clients' byte streams, each sent on a connection of its own within one example."""
    return st.lists(stream, min_size=1, max_size=4)


# ---------------------------------------------------------------------------------------------------- RTDE (30004)
RTDE_KINDS = (
    rp.REQUEST_PROTOCOL_VERSION,
    rp.GET_URCONTROL_VERSION,
    rp.TEXT_MESSAGE,
    rp.DATA_PACKAGE,
    rp.SETUP_OUTPUTS,
    rp.SETUP_INPUTS,
    rp.START,
    rp.PAUSE,
)
_NAMES = sorted(rp.OUTPUT_TYPES) + sorted(rp.INPUT_TYPES) + ["", "bogus", "ft_raw_wrench", "actual_q ", "ACTUAL_Q"]
names_csv = st.one_of(
    st.lists(st.sampled_from(_NAMES), max_size=8).map(lambda names: ",".join(names).encode()),
    st.lists(st.text(max_size=12), max_size=4).map(lambda names: ",".join(names).encode()),
    st.binary(max_size=48),
)
_frequency = st.floats(allow_nan=True, allow_infinity=True).map(lambda f: struct.pack(">d", f))
_RTDE_PAYLOADS = {
    rp.REQUEST_PROTOCOL_VERSION: st.one_of(st.integers(0, 4), st.integers(0, 0xFFFF)).map(
        lambda v: struct.pack(">H", v)
    )
    | st.binary(max_size=4),
    rp.SETUP_OUTPUTS: st.one_of(st.tuples(_frequency, names_csv).map(b"".join), names_csv, st.binary(max_size=12)),
    rp.SETUP_INPUTS: names_csv,
    rp.DATA_PACKAGE: st.tuples(st.integers(0, 3).map(lambda i: bytes([i])), st.binary(max_size=64)).map(b"".join)
    | st.just(b""),
}
rtde_package = st.one_of(
    st.sampled_from(RTDE_KINDS).flatmap(
        lambda kind: _RTDE_PAYLOADS.get(kind, st.binary(max_size=8)).map(lambda p: rp.pack(kind, p))
    ),
    st.tuples(st.integers(0, 255), st.binary(max_size=32)).map(lambda kp: rp.pack(*kp)),
)
LARGE_RTDE = (
    rp.pack(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"actual_q," * 1400),  # a data package over 65535 bytes
    rp.pack(rp.SETUP_OUTPUTS, struct.pack(">d", 125.0) + b"a," * 20000),  # an answer over 65535 bytes
    rp.pack(rp.SETUP_OUTPUTS, b"a," * 30000),  # the same in protocol version 1
    rp.pack(rp.SETUP_INPUTS, b"external_force_torque," * 2900),  # an input data package over 65535 bytes
    rp.pack(rp.GET_URCONTROL_VERSION) * 5000,  # 15 kB of requests, 80 kB of answers
)
V2 = rp.pack(rp.REQUEST_PROTOCOL_VERSION, struct.pack(">H", 2))


@st.composite
def rtde_input_session(draw: st.DrawFn) -> bytes:
    """A version 2 client that sets a valid input recipe up and sends data packages of the right size."""
    names = draw(st.lists(st.sampled_from(sorted(rp.INPUT_TYPES)), min_size=1, max_size=5, unique=True))
    size = rp.recipe_struct([rp.INPUT_TYPES[n] for n in names]).size - 1
    packages = draw(st.lists(st.binary(min_size=size, max_size=size), min_size=1, max_size=4))
    setup = rp.pack(rp.SETUP_INPUTS, ",".join(names).encode())
    return V2 + setup + b"".join(rp.pack(rp.DATA_PACKAGE, b"\x01" + p) for p in packages)


rtde_stream = st.one_of(
    st.lists(rtde_package, min_size=1, max_size=12).map(b"".join),
    st.tuples(st.booleans(), st.lists(rtde_package, min_size=1, max_size=12)).map(
        lambda v_ps: (V2 if v_ps[0] else b"") + b"".join(v_ps[1])
    ),
    rtde_input_session(),
    st.binary(min_size=1, max_size=96),  # framing: any size field, including the impossible 0-2
    st.sampled_from(LARGE_RTDE),
)
"""All bytes one RTDE client sends."""
chunk_sizes = st.lists(st.integers(1, 4096), min_size=1, max_size=6)
"""How those bytes are cut into separate sends (the last size repeats)."""

# ----------------------------------------------------------------------------------------------- dashboard (29999)
DASHBOARD_COMMANDS = (
    "robotmode",
    "polyscopeversion",
    "get robot model",
    "get loaded program",
    "safetymode",
    "safetystatus",
    "programstate",
    "running",
    "close safety popup",
    "is in remote control",
    "stop",
    "pause",
    "play",
    "power on",
    "power off",
    "brake release",
    "unlock protective stop",
    "load /programs/drill.urp",
    "load installation default.installation",
    "quit",
    "shutdown",
    "popup hello",
    "",
)
_command = st.sampled_from(DASHBOARD_COMMANDS).flatmap(
    lambda c: st.sampled_from([c, c.upper(), f"  {c}  ", c.replace(" ", "\t")])
)
_line_end = st.sampled_from([b"\n", b"\r\n", b"\r", b""])
dashboard_line = st.tuples(st.one_of(_command, st.text(max_size=80)).map(lambda t: t.encode()), _line_end).map(b"".join)
dashboard_stream = st.one_of(
    st.lists(st.one_of(dashboard_line, st.binary(max_size=64)), min_size=1, max_size=20).map(b"".join),
    st.integers(4097, 9000).map(lambda n: b"x" * n),  # a line past the 4 KiB bound
    st.just(b"robotmode\n" * 3000),  # 30 kB of commands at once
)

# -------------------------------------------------------------------------------- script ports (30001-30003)
_statement = st.one_of(
    st.tuples(st.integers(-2, 9), st.sampled_from(["True", "False", "1", "maybe"])).map(
        lambda nb: f"set_standard_digital_out({nb[0]}, {nb[1]})"
    ),
    st.sampled_from(['textmsg("hi")', "sleep(0.1)", "movel(p[0,0,0,0,0,0])", "end", "def", "sec", "halt"]),
    st.text(max_size=40).filter(lambda t: "\n" not in t),
)
_body = st.lists(_statement, max_size=6).map(lambda lines: "".join(f"  {line}\n" for line in lines))
_program = st.one_of(
    st.tuples(st.sampled_from(["def", "sec"]), st.sampled_from(["f", "rtde_control", "spindle_on"]), _body).map(
        lambda p: f"{p[0]} {p[1]}():\n{p[2]}end\n"
    ),
    st.tuples(st.integers(-1, 400), _body).map(  # named like ur_rtde's control script, with a register offset
        lambda p: f"def rtde_control():\n  reg_offset_int = # int register offset\n{p[0]}\n{p[1]}end\n"
    ),
    _body,
)
script_stream = st.one_of(
    st.tuples(_program, st.booleans()).map(lambda pc: (pc[0].replace("\n", "\r\n") if pc[1] else pc[0]).encode()),
    st.binary(min_size=1, max_size=256),
    st.text(max_size=200).map(lambda t: t.encode()),
    st.just(b"def never_ends():\n" + b"  sleep(1)\n" * 200),  # a program without its end line
)

# --------------------------------------------------------------------------------- Net F/T (UDP 49152, TCP 49151)
_rdt_request = st.tuples(
    st.sampled_from([0x1234, 0x1235, 0]),
    st.sampled_from([CMD_START_REALTIME, CMD_STOP, CMD_SET_SOFTWARE_BIAS, 0, 7, 0xFFFF]),
    st.integers(0, 0xFFFFFFFF),
).map(lambda r: struct.pack(">HHI", *r))
ft_datagram = st.one_of(_rdt_request, st.binary(max_size=64))
tracker_datagram = st.binary(max_size=64)
ft_cal_stream = st.binary(min_size=1, max_size=64)

# --------------------------------------------------------------------------------- control port (TCP 30100, JSON)
SAFE_CONTROL_COMMANDS = ("status", "events", "truth", "contract", "specimen", "ft_load", "nope", "")
"""Control commands that leave the RTDE stream alone (``fault``, ``clear_faults`` and ``shutdown`` change it)."""
_json_value = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=8,
)
_control_object = st.tuples(
    st.sampled_from(SAFE_CONTROL_COMMANDS),
    st.dictionaries(st.sampled_from(["seed", "mass_kg", "force_n"]), _json_value),
).map(lambda ca: json.dumps({"cmd": ca[0], **ca[1]}).encode() + b"\n")
control_stream = st.one_of(
    st.lists(st.one_of(_control_object, dashboard_line, st.binary(max_size=64)), min_size=1, max_size=8).map(b"".join),
    st.integers(1, 4000).map(lambda depth: b"[" * depth + b"]" * depth + b"\n"),  # deep nesting
)
