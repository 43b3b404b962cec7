"""What the emulator relies on in ``ur_rtde`` 1.6.5, and a check that a client still does the same.

The emulator re-implements the behaviour of ``ur_rtde``'s uploaded control program (not its text) and decodes
the client's input recipes by position. A new ``ur_rtde`` release that renumbers recipes, changes a recipe's
fields, the register protocol or the handling of a command the emulator implements would make the emulator
silently wrong; :func:`check_contract` compares what a real client set up and uploaded with what is recorded
here (run by ``tests/real/test_real_contract.py``). The program text is compared by SHA-256 digests of the parts the
emulator mirrors, never stored.
"""

from __future__ import annotations

import hashlib
import re
from typing import Any

from drillgym.envs.real.emulator.script import PROGRAM_HEADER, REALTIME_COMMANDS

UR_RTDE_VERSION = "1.6.5"


def _regs(kind: str, indices: range | list[int]) -> list[str]:
    return [f"{kind}_register_{i}" for i in indices]


CONTROL_OUTPUTS = [
    "timestamp",
    "robot_status_bits",
    "safety_status_bits",
    "runtime_state",
    *_regs("output_int", range(3)),
    *_regs("output_double", range(6)),
]
"""Output recipe of ``RTDEControlInterface`` on a CB3 >= 3.4 (lower register range)."""
RECEIVE_DEFAULT_OUTPUTS = 57
"""Variables of ``RTDEReceiveInterface``'s default recipe for PolyScope 3.15."""
INPUT_RECIPE_COUNT = 23
"""Input recipes ``RTDEControlInterface`` sets up (default flags)."""
_I0, _I1 = "input_int_register_0", "input_int_register_1"
INPUT_RECIPES: dict[int, list[str]] = {
    1: [_I0, *_regs("input_double", range(8)), _I1],
    2: [_I0, *_regs("input_double", range(11))],
    4: [_I0],
    6: [_I0, *_regs("input_double", range(6))],
    8: [_I0, "input_double_register_0"],
    11: [_I0],
    19: [_I0, "input_double_register_0", _I1],
    23: [_I0, "external_force_torque"],
}
"""The recipes behind the commands the emulator implements (moveL 1, servoL 2, clear/stop script 4, setTcp 6,
servoStop / setWatchdog 8, watchdog kick 11, stopL 19) and the last one (its position shows the count)."""
LOADED_MESSAGE = 'textmsg("RTDE Control Script Loaded (14.02.2024-12:23)")'
OFFSET_INJECTIONS = ("reg_offset_float = # float register offset\n0", "reg_offset_int = # int register offset\n0")
MIRRORED_COMMANDS = (0, 3, 15, 16, 24, 29, 33, 35, 255)
"""Command ids whose program blocks the emulator mirrors (0: the idle branch, via ``rtde_cmd``)."""
PROGRAM_DIGESTS: dict[str, str] = {
    "signal_ready": "6af2fc996c786474",
    "signal_done_with_cmd": "9d16530381f4fc3c",
    "rtde_cmd": "55dbf8084fce444c",
    "cmd_3": "711d094ebc4c7681",
    "cmd_15": "0e055b3f496deafe",
    "cmd_16": "716d77ab04a402f7",
    "cmd_24": "421793576240d044",
    "cmd_29": "3cf90b1ea88fff62",
    "cmd_33": "8e15a76d54e29115",
    "cmd_35": "e2217d06d559fd51",
    "cmd_255": "57f5e9418a494e2c",
    "main_loop": "5eba72650dc8a771",
}
"""SHA-256 (first 16 hex digits) of each mirrored part of the program ur_rtde 1.6.5 uploads to a 3.15 CB3."""

_BLOCK_RE = re.compile(r"\n[ \t]*(?:if|elif) cmd == (\d+):\n")


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def _function(text: str, name: str) -> str:
    m = re.search(rf"\n([ \t]*)def {name}\(\S*\):\n(.*?)\n\1end\n", text, re.S)
    return m.group(2) if m else ""


def program_parts(script: str) -> dict[str, str]:
    """Digests of the parts of an uploaded ``rtde_control`` program that the emulator mirrors."""
    parts = {name: _digest(_function(script, name)) for name in ("signal_ready", "signal_done_with_cmd", "rtde_cmd")}
    process = _function(script, "process_cmd")
    pieces = _BLOCK_RE.split(process)
    blocks = {int(pieces[i]): pieces[i + 1] for i in range(1, len(pieces) - 1, 2)}
    for cmd in MIRRORED_COMMANDS:
        if cmd:
            parts[f"cmd_{cmd}"] = _digest(blocks.get(cmd, ""))
    start = script.find("# NODE_CONTROL_LOOP_BEGINS")
    parts["main_loop"] = _digest(script[start:]) if start >= 0 else ""
    return parts


def realtime_commands(script: str) -> set[int]:
    """The command ids the program's main loop treats as real-time."""
    m = re.search(r"\n[ \t]*if (cmd == \d+(?: or cmd == \d+)*):\n[ \t]*# for realtime commands", script)
    return {int(x) for x in re.findall(r"cmd == (\d+)", m.group(1))} if m else set()


def check_contract(contract: dict[str, Any]) -> list[str]:
    """Differences between a client's setup (the emulator's ``contract`` reply) and what the emulator assumes."""
    problems = []
    outputs = contract["output_recipes"]
    if CONTROL_OUTPUTS not in outputs:
        problems.append(f"RTDEControlInterface output recipe changed; seen {outputs}")
    if not any(len(o) == RECEIVE_DEFAULT_OUTPUTS for o in outputs):
        problems.append(f"RTDEReceiveInterface default recipe no longer has {RECEIVE_DEFAULT_OUTPUTS} variables")
    control_inputs: list[list[str]] = max(contract["input_recipes"], key=len, default=[])
    if len(control_inputs) != INPUT_RECIPE_COUNT:
        problems.append(f"{len(control_inputs)} input recipes set up, expected {INPUT_RECIPE_COUNT}")
    for rid, names in INPUT_RECIPES.items():
        seen = control_inputs[rid - 1] if len(control_inputs) >= rid else None
        if seen != names:
            problems.append(f"input recipe {rid} is {seen}, the emulator decodes {names}")
    script = contract["script"]
    if not script.startswith(PROGRAM_HEADER + "\n"):
        problems.append(f"the uploaded program does not start with {PROGRAM_HEADER!r}")
    for marker in (LOADED_MESSAGE, *OFFSET_INJECTIONS):
        if marker not in script:
            problems.append(f"marker {marker!r} missing from the uploaded program")
    if realtime_commands(script) != set(REALTIME_COMMANDS):
        problems.append(
            f"real-time commands are {sorted(realtime_commands(script))}, the emulator assumes "
            f"{sorted(REALTIME_COMMANDS)}"
        )
    for part, digest in program_parts(script).items():
        if digest != PROGRAM_DIGESTS.get(part):
            problems.append(f"program part {part} changed (sha256 {digest}, recorded {PROGRAM_DIGESTS.get(part)})")
    return problems
