"""The emulator's JSON control port: one JSON object per line in, one per line out.

Requests (``{"cmd": ...}``): ``status``; ``fault`` with ``kind`` (``protective_stop``, ``drop_link`` and
``freeze_rtde`` [``value``: seconds, 0 = until cleared], ``delay`` [``value``: seconds], ``stale_ft``,
``stale_tracker``); ``clear_faults``; ``truth`` (privileged true-tip metrics of the current specimen);
``events`` (what the control program did); ``ft_load`` (a known load on the F/T sensor, sensor frame: ``mass_kg``
hung from the tool, m·g along -z, or ``force_n`` [fx, fy, fz]; 0 / [0, 0, 0] removes it); ``contract`` (recipes set up and the uploaded program, for the
``ur_rtde`` contract test); ``shutdown``. Replies carry ``"ok": true`` or ``"ok": false, "error": ...``.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

import numpy as np

STANDARD_GRAVITY_M_S2 = 9.80665

if TYPE_CHECKING:
    from drillgym.envs.real.emulator.host import EmulatorHost


BAD_ARGUMENT_ERRORS = (KeyError, ValueError, TypeError, ArithmeticError, IndexError)
"""What a request's arguments can raise (a missing key, text for a number, ``1e999`` to ``int``, a short vector):
answered ``"ok": false``, the connection and the emulator go on."""


def handle_control(emulator: EmulatorHost, line: str) -> tuple[dict[str, Any], bool]:
    """Reply to one request line, and whether to close the control connection.

    Any line gets a reply: one that is not a JSON object with a string ``"cmd"`` (nesting too deep for the parser
    included) and any bad argument get ``"ok": false`` with the error.
    """
    try:
        request, cmd = parse_request(line)
    except (ValueError, KeyError, TypeError, RecursionError) as e:
        return {"ok": False, "error": f"bad request {line[:200]!r}: {type(e).__name__}: {e}"}, False
    try:
        return _answer(emulator, request, cmd)
    except BAD_ARGUMENT_ERRORS as e:
        return {"ok": False, "error": f"{cmd}: {e}"}, False


def parse_request(line: str) -> tuple[dict[str, Any], str]:
    """The request object of one line and its ``cmd``; ``ValueError`` / ``TypeError`` / ``KeyError`` if it is none."""
    request = json.loads(line)
    if not isinstance(request, dict):
        raise TypeError(f"expected a JSON object, got {type(request).__name__}")
    cmd = request["cmd"]
    if not isinstance(cmd, str):
        raise TypeError(f"cmd must be a string, got {type(cmd).__name__}")
    return request, cmd


def _answer(emulator: EmulatorHost, request: dict[str, Any], cmd: str) -> tuple[dict[str, Any], bool]:
    """The reply to one parsed request (its arguments may raise :data:`BAD_ARGUMENT_ERRORS`)."""
    t = emulator.now()
    if cmd == "status":
        return {"ok": True, **status(emulator)}, False
    if cmd == "fault":
        emulator.faults.apply(emulator, str(request["kind"]), float(request.get("value", 0.0)), t)
        return {"ok": True}, False
    if cmd == "clear_faults":
        emulator.faults.clear(emulator, t)
        return {"ok": True}, False
    if cmd == "truth":
        world = emulator.world
        centre = world.cell.hole.centre_at(world.scenario.entry_depth_m)
        metrics = world.truth.metrics(centre)
        return {
            "ok": True,
            "specimen": world.specimen,
            "specimen_seed": world.specimen_seed,
            "hardness_factor": world.hardness_factor,
            **metrics,
        }, False
    if cmd == "specimen":
        world = emulator.world
        now = world.seed_specimen(int(request["seed"]))
        return {
            "ok": True,
            "replaced_now": now,
            "specimen": world.specimen,
            "seed": world.specimen_seed if now else world.next_specimen_seed,
            "hardness_factor": world.hardness_factor if now else None,
        }, False
    if cmd == "ft_load":
        return {"ok": True, "force_n": ft_load(emulator, request)}, False
    if cmd == "events":
        events = [{"t_s": e.t_s, "cmd": e.cmd, "detail": e.detail} for e in emulator.program.events]
        return {"ok": True, "events": events}, False
    if cmd == "contract":
        return {
            "ok": True,
            "output_recipes": emulator.output_recipes,
            "input_recipes": emulator.input_recipes,
            "script": emulator.program.script_text,
        }, False
    if cmd == "shutdown":
        emulator.shutdown = True
        return {"ok": True}, True
    return {"ok": False, "error": f"unknown cmd {cmd[:80]!r}"}, False


def ft_load(emulator: EmulatorHost, request: dict[str, Any]) -> list[float]:
    """Hang a known load on the F/T sensor (``mass_kg``: m·g along the sensor's -z; or ``force_n``, N)."""
    if "force_n" in request:
        force = np.asarray(request["force_n"], dtype=float).reshape(3)
    else:
        force = np.array([0.0, 0.0, -float(request["mass_kg"]) * STANDARD_GRAVITY_M_S2])
    if not np.all(np.isfinite(force)):
        raise ValueError(f"load {force.tolist()} is not finite")
    emulator.world.ft_external = np.concatenate([force, np.zeros(3)])
    return [float(v) for v in force]


def status(emulator: EmulatorHost) -> dict[str, Any]:
    """State of the emulated controller, its program and its streams."""
    prog, world = emulator.program, emulator.world
    return {
        "t_s": emulator.now(),
        "runtime_state": prog.runtime_state.name,
        "stop_reason": prog.stop_reason,
        "protective_stopped": world.halted,
        "scripts_loaded": prog.scripts_loaded,
        "command_counts": {str(k): v for k, v in sorted(prog.counts.items())},
        "unsupported_commands": {str(k): v for k, v in sorted(prog.unsupported.items())},
        "servo_updates": prog.servo_updates,
        "servo_ticks_without_update": prog.servo_ticks_without_update,
        "servo_active": prog.servo_active,
        "last_servo_pose": prog.last_servo_pose,
        "watchdog_hz": prog.watchdog_hz,
        "tcp_pose": world.tcp_pose().tolist(),
        "rigid_tip_task_m": world.cell.rigid_tip.tolist(),
        "specimen": world.specimen,
        "controller_ticks": emulator.controller_ticks,
        "late_ticks": emulator.late_ticks,
        "rtde_connections": len(emulator.rtde),
        "rtde_packages_in": emulator.regs.packages,
        "ft_records_sent": emulator.sensors.ft_sent,
        "ft_records_lost": emulator.sensors.ft_lost,
        "ft_bad_requests": emulator.sensors.bad_requests,
        "faults": emulator.faults.describe(),
        "orientation_warnings": world.orientation_warnings,
    }
