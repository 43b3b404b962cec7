"""The shipped recording session (tests/data/rtde_session_emulator/): a shallow li2023 hole on the emulator, its
robot state recorded by ur_rtde's own ``startFileRecording``, made with ``drillgym.eval.real.record_session``
(its docstring has the command). ``rtde_session_emulator_env_log.parquet`` is the env's own log of the same run."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from drillgym.eval.diagnosis.episodes import episode_from_log
from drillgym.eval.diagnosis.rtde_import import RTDE_Q, RTDE_TCP, import_session
from drillgym.eval.logs import read_episode_log
from drillgym.eval.logs.schema import LOG_SCHEMA_VERSION

DATA = Path(__file__).resolve().parents[1] / "data"
SESSION = DATA / "rtde_session_emulator"
ENV_LOG = DATA / "rtde_session_emulator_env_log.parquet"


def test_the_shipped_session_is_small_and_in_ur_rtdes_format():
    assert sum(p.stat().st_size for p in SESSION.iterdir()) < 300_000
    assert sorted(p.name for p in SESSION.iterdir()) == [
        "commands.csv",
        "ft.csv",
        "header.json",
        "rtde.csv",
        "tracker.csv",
    ]
    lines = (SESSION / "rtde.csv").read_text().splitlines()
    assert lines[0].split(",") == [
        "timestamp",
        *RTDE_Q,
        *RTDE_TCP,
        "actual_TCP_pose_3",
        "actual_TCP_pose_4",
        "actual_TCP_pose_5",
    ]
    assert all(len(v.split(".")[1]) == 6 for v in lines[1].split(","))  # ur_rtde: std::fixed, 6 decimals


def test_import_rtde_imports_the_shipped_session(tmp_path):
    from drillgym.eval.cli import main

    assert main(["import-rtde", str(SESSION), "--out", str(tmp_path)]) == 0
    header, frame = read_episode_log(tmp_path / "rtde_session_emulator.parquet")
    assert header["source"] == "real" and header["schema_version"] == LOG_SCHEMA_VERSION
    assert header["controller"]["name"] == "li2023" and header["scenario"]["depth_mm"] == 3.0
    # the importer's only repair is dropping the states ur_rtde wrote twice; the diagnosis's checks add none
    assert all(r.endswith("repeated robot state(s) dropped") for r in header["run"]["repairs"])
    expected = {
        "t_s",
        "step",
        "phase",
        "depth_cmd_m",
        "ft_fx_n",
        "ft_fz_n",
        "ft_tz_nm",
        "cmd_dx_base_m",
        "cmd_feed_scale",
        "q0_rad",
        "q5_rad",
        "tcp_x_base_m",
        "tcp_z_base_m",
        "tracker_x_base_m",
        "tracker_err_y_base_m",
        "tracker_valid",
    }
    assert expected <= set(frame.columns) and not [c for c in frame.columns if c.startswith("sim_")]
    assert 2.0 < frame["t_s"].iloc[-1] - frame["t_s"].iloc[0] < 6.0  # a 3 mm hole at 3 mm/s and its approach
    np.testing.assert_allclose(np.diff(frame["t_s"]), 0.01, atol=1e-6)  # 100 Hz F/T rows
    assert set(frame["phase"]) == {0, 1, 2} and frame["tracker_valid"].all()
    assert frame["ft_fz_n"].abs().max() > 5.0  # it drilled
    assert frame["depth_cmd_m"].max() == pytest.approx(0.003, abs=2e-4)  # drilled to 3 mm, then retracted


def test_the_import_agrees_with_the_envs_own_log_of_the_run():
    """The recording's clock (controller timestamps put on the episode clock through
    clock.rtde_timestamp_at_t0_s) lines the robot states up with the steps the env logged them in."""
    header, frame = import_session(SESSION)
    assert episode_from_log("session", header, frame).repairs == []
    _, env = read_episode_log(ENV_LOG)
    assert len(frame) == len(env)
    np.testing.assert_array_equal(frame["step"], env["step"])
    for col in ("ft_fx_n", "ft_fz_n", "ft_ty_nm", "cmd_dx_base_m", "cmd_feed_scale", "tracker_x_base_m"):
        np.testing.assert_allclose(frame[col], env[col], atol=1e-6, err_msg=col)
    # the same robot state, or the one next to it (one RTDE period, 8 ms, of motion)
    for col in [f"q{i}_rad" for i in range(6)]:
        np.testing.assert_allclose(frame[col], env[col], atol=1e-3, err_msg=col)
    for col in ("tcp_x_base_m", "tcp_y_base_m", "tcp_z_base_m"):
        np.testing.assert_allclose(frame[col], env[col], atol=5e-4, err_msg=col)
