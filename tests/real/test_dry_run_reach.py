"""``drillgym run --dry-run``: how far the commanded targets go from the entry point (the checklist's question)."""

import json
import math

import numpy as np
import pytest
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.envs.cell_params import R_BASE_TASK
from drillgym.envs.real.config import SafetyLimits
from drillgym.eval.real.dry_run import correction_reach_m, describe_reach, target_reach

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)

ENTRY_BASE_M = np.array([-0.45, -0.11, 0.10])
ROTVEC = [math.pi, 0.0, 0.0]  # any orientation: the summary reads positions only


def _T() -> np.ndarray:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_BASE_TASK, ENTRY_BASE_M
    return T


def _write(path, commands):
    with open(path, "w") as f:
        for cmd, p_task_m in commands:
            p_base = ENTRY_BASE_M + R_BASE_TASK @ np.asarray(p_task_m, dtype=float)
            f.write(json.dumps({"t": 0.0, "cmd": cmd, "args": [[*p_base.tolist(), *ROTVEC], 0.5], "sent": False}))
            f.write("\n")
    return path


def test_reach_of_hand_placed_targets_in_the_task_frame(tmp_path):
    # task frame: x = +y_base, y = +x_base, z = -z_base (into the bone); values in m, expected in mm by hand
    log = _write(
        tmp_path / "commands.jsonl",
        [
            ("setTcp", [0.0, 0.0, 0.0]),  # not a target (its "pose" is the TCP offset): ignored
            ("moveL", [0.0, 0.0, -3e-3]),  # the start pose, 3 mm above the entry
            ("servoL", [0.0, 0.0, -3e-3]),
            ("servoL", [0.3e-3, -0.4e-3, 2e-3]),  # 0.5 mm lateral (3-4-5)
            ("servoL", [-0.1e-3, 0.0, 6e-3]),  # the bottom of a 6 mm hole
        ],
    )
    reach = target_reach(log, _T(), depth_m=6e-3)
    assert reach["servo_targets"] == 3 and reach["first_target_from_start_pose_mm"] == pytest.approx(0.0, abs=1e-9)
    assert reach["commanded"]["max_lateral_mm"] == pytest.approx(0.5, abs=1e-9)
    assert reach["commanded"]["max_depth_mm"] == pytest.approx(6.0, abs=1e-9)
    assert reach["commanded"]["max_above_entry_mm"] == pytest.approx(3.0, abs=1e-9)
    assert reach["start_pose"] == pytest.approx({"lateral_mm": 0.0, "above_entry_mm": 3.0}, abs=1e-9)
    assert reach["plan"] == pytest.approx({"lateral_mm": 0.0, "depth_mm": 6.0, "above_entry_mm": 3.0})
    # 2 mm per base axis; the cell's task axes are base axes, so 2·√2 mm lateral and 2 mm along the drill
    assert reach["correction_limit"] == pytest.approx(
        {"per_base_axis_mm": 2.0, "lateral_mm": 2 * 2**0.5, "axial_mm": 2.0}
    )
    assert reach["worst_case"] == pytest.approx({"max_lateral_mm": 2 * 2**0.5, "max_depth_mm": 8.0})
    assert reach["workspace_stop"] == pytest.approx({"lateral_mm": 6.0, "above_entry_mm": 20.0, "depth_mm": 8.0})
    text = describe_reach(reach, log)
    assert "lateral up to 0.500 mm, depth up to 6.000 mm" in text
    assert "lateral up to 2.828 mm, depth up to 8.000 mm" in text


def test_correction_reach_of_a_tilted_axis_and_a_smaller_clip():
    tilt = math.radians(30.0)  # drill axis tilted 30° about the base x axis
    R = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(tilt), -math.sin(tilt)], [0.0, math.sin(tilt), math.cos(tilt)]])
    lateral_m, axial_m = correction_reach_m(R, 1e-3)
    # corners of the ±1 mm cube: axial = sin30 + cos30 = 1.366 mm; lateral = hypot(1, cos30 + sin30) = 1.693 mm
    assert axial_m == pytest.approx(1e-3 * (0.5 + 3**0.5 / 2))
    assert lateral_m == pytest.approx(1e-3 * math.hypot(1.0, 0.5 + 3**0.5 / 2))
    limits = SafetyLimits(max_correction_m=1e-3)
    assert limits.max_correction_m == 1e-3


def test_a_log_without_servo_targets_is_refused(tmp_path):
    log = _write(tmp_path / "commands.jsonl", [("moveL", [0.0, 0.0, -3e-3])])
    with pytest.raises(ValueError, match="no servoL"):
        target_reach(log, _T(), depth_m=6e-3)


@pytest.mark.realtime  # a whole (shallow, fast) dry-run episode against the emulator
def test_run_dry_run_prints_and_writes_the_reach(start_emulator, tmp_path, capsys):
    from drillgym.eval.cli import main

    emu = start_emulator()
    out = tmp_path / "dry"
    scenario = "beta_deg=0,depth_mm=2,feed_mm_s=2"
    args = ["run", "--robot", emu.host, "--tracker", f"udp:{emu.host}", "--scenario", scenario]
    assert main([*args, "--controller", "li2023", "--dry-run", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "DRY RUN reach from the entry point" in printed and "worst case with the compensator's" in printed
    reach = json.loads((out / "dry_run.json").read_text())
    assert reach["servo_targets"] > 100 and emu.status()["command_counts"] == {}  # nothing sent
    assert reach["commanded"]["max_depth_mm"] == pytest.approx(2.0, abs=1e-6)  # the path reached the plan's depth
    # nothing moved, so the stream ramps from where the emulated robot stands (10 mm above the entry) to the path
    assert reach["commanded"]["max_above_entry_mm"] == pytest.approx(10.0, abs=0.5)
    assert reach["first_target_from_start_pose_mm"] == pytest.approx(7.0, abs=0.5)
    assert reach["commanded"]["max_lateral_mm"] <= reach["correction_limit"]["lateral_mm"] + 1e-9
    assert reach["start_pose"]["lateral_mm"] < 1e-6 and reach["start_pose"]["above_entry_mm"] == pytest.approx(3.0)
    assert reach["worst_case"]["max_depth_mm"] == pytest.approx(4.0)
