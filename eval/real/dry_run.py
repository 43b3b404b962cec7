"""How far a dry run's commanded targets go from the entry point: what the operator checks before the first hole.

``drillgym run --dry-run`` logs every command that would have been sent in ``<out>/commands.jsonl``. The
checklist in ``docs/deployment.md`` asks that those targets stay within a few mm of the entry point;
:func:`target_reach` measures it, in the task frame (origin at the registered entry point, z along the planned
drill axis into the bone, x and y lateral):

* what the dry run commanded: the largest lateral distance and depth of the ``servoL`` targets, how high above
  the entry they started, and the start pose of the ``moveL`` (3 mm above the entry, on the axis);
* the plan: on the axis, from ``APPROACH_START_M`` above the entry to ``depth_m``;
* the worst case the compensator can add to the plan: its correction is clipped to ``max_correction_m`` per
  *base* axis, so in the task frame it reaches the largest lateral norm and axial component of the corners of
  that cube turned by ``R_base_task`` (2·√2 mm lateral and 2 mm axial with the default 2 mm and the cell's axes);
* the workspace box that stops the episode (``SafetyLimits``).

A dry run moves nothing, so its corrections answer a robot at rest (no contact force): its targets show the
plan and the frames, the worst case bounds what a real hole can command. Nor does it move to the start pose:
the servo stream starts from the robot's measured TCP and ramps (rate-limited) to the path, so the first
targets lie between where the robot stands and the start pose; ``first_target_from_start_pose_mm`` says how far
that is (a real run refuses to start beyond ``reset_max_distance_m``, 50 mm).
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs.constants import APPROACH_START_M
from drillgym.envs.errors import UserError
from drillgym.envs.real.config import SafetyLimits

MM = 1e3


def correction_reach_m(R_base_task: np.ndarray, max_correction_m: float) -> tuple[float, float]:
    """Largest lateral norm and axial component (task frame, m) of a correction clipped per base axis."""
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=3))) * max_correction_m
    in_task = corners @ np.asarray(R_base_task, dtype=float)  # rows: R^T c for each corner c
    return float(np.max(np.hypot(in_task[:, 0], in_task[:, 1]))), float(np.max(in_task[:, 2]))


def _task_points(commands_path: Path, name: str, entry_base_m: np.ndarray, R_base_task: np.ndarray) -> np.ndarray:
    """Task-frame positions (m, N x 3) of the poses of every ``name`` command in the log."""
    points = []
    with open(commands_path) as f:
        for line in f:
            if not line.strip():
                continue
            entry = json.loads(line)
            if entry.get("cmd") == name and entry.get("args"):
                points.append(np.asarray(entry["args"][0][:3], dtype=float))
    if not points:
        return np.zeros((0, 3))
    return (np.array(points) - entry_base_m) @ R_base_task


def target_reach(
    commands_path: str | Path,
    T_base_task: np.ndarray,
    depth_m: float,
    limits: SafetyLimits | None = None,
) -> dict[str, Any]:
    """How far the logged targets, the plan and its worst-case correction go from the entry point (mm).

    ``T_base_task``: the task frame in the base frame (4x4; the env's ``T_base_task``); ``depth_m``: the
    planned depth. Raises ``OSError`` if the log cannot be read, ``ValueError`` if it holds no ``servoL``.
    """
    lim = limits or SafetyLimits()
    T = np.asarray(T_base_task, dtype=float)
    R, entry = T[:3, :3], T[:3, 3]
    servo = _task_points(Path(commands_path), "servoL", entry, R)
    if len(servo) == 0:
        raise UserError(f"{commands_path} holds no servoL command: the dry run streamed nothing")
    start = _task_points(Path(commands_path), "moveL", entry, R)
    lateral_c, axial_c = correction_reach_m(R, lim.max_correction_m)
    lateral = np.hypot(servo[:, 0], servo[:, 1])
    start_task = np.array([0.0, 0.0, -APPROACH_START_M])
    return {
        "servo_targets": len(servo),
        "first_target_from_start_pose_mm": float(np.linalg.norm(servo[0] - start_task) * MM),
        "commanded": {
            "max_lateral_mm": float(lateral.max() * MM),
            "max_depth_mm": float(servo[:, 2].max() * MM),
            "max_above_entry_mm": float(-servo[:, 2].min() * MM),
        },
        "start_pose": None
        if len(start) == 0
        else {
            "lateral_mm": float(np.hypot(start[0, 0], start[0, 1]) * MM),
            "above_entry_mm": float(-start[0, 2] * MM),
        },
        "plan": {"lateral_mm": 0.0, "depth_mm": depth_m * MM, "above_entry_mm": APPROACH_START_M * MM},
        "correction_limit": {
            "per_base_axis_mm": lim.max_correction_m * MM,
            "lateral_mm": lateral_c * MM,
            "axial_mm": axial_c * MM,
        },
        "worst_case": {"max_lateral_mm": lateral_c * MM, "max_depth_mm": (depth_m + axial_c) * MM},
        "workspace_stop": {
            "lateral_mm": lim.workspace_lateral_m * MM,
            "above_entry_mm": lim.workspace_above_m * MM,
            "depth_mm": (depth_m + lim.workspace_below_m) * MM,
        },
    }


def describe_reach(reach: dict[str, Any], commands_path: str | Path) -> str:
    """The summary as the operator reads it (several lines)."""
    c, w, lim, ws = reach["commanded"], reach["worst_case"], reach["correction_limit"], reach["workspace_stop"]
    lines = [
        f"DRY RUN reach from the entry point (task frame: z along the drill axis into the bone), "
        f"{reach['servo_targets']} servoL targets in {commands_path}:",
        f"  commanded:  lateral up to {c['max_lateral_mm']:.3f} mm, depth up to {c['max_depth_mm']:.3f} mm, "
        f"from {c['max_above_entry_mm']:.3f} mm above the entry",
        f"  first target {reach['first_target_from_start_pose_mm']:.3f} mm from the start pose: a dry run does not "
        "move to it, so the targets ramp (rate-limited) from where the robot stands, and 'above the entry' and "
        "'lateral' include that ramp",
    ]
    if reach["start_pose"] is not None:
        s = reach["start_pose"]
        lines.append(
            f"  start pose (moveL): {s['lateral_mm']:.3f} mm lateral, {s['above_entry_mm']:.3f} mm above the entry"
        )
    lines += [
        f"  plan:       on the axis, {reach['plan']['above_entry_mm']:.3f} mm above the entry to "
        f"{reach['plan']['depth_mm']:.3f} mm deep",
        f"  worst case with the compensator's correction limit ({lim['per_base_axis_mm']:g} mm per base axis): "
        f"lateral up to {w['max_lateral_mm']:.3f} mm, depth up to {w['max_depth_mm']:.3f} mm",
        f"  workspace stop beyond |x|, |y| {ws['lateral_mm']:g} mm, {ws['above_entry_mm']:g} mm above the entry, "
        f"{ws['depth_mm']:g} mm deep",
    ]
    return "\n".join(lines)
