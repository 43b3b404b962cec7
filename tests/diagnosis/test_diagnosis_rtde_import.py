"""The ur_rtde session importer, on files written in ur_rtde's file-recording format."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from test_diagnosis_helpers import RTDE_T0, sim_log, write_session

from drillgym.eval.diagnosis.episodes import episode_from_log, load_episodes
from drillgym.eval.diagnosis.rtde_import import import_session, read_rtde_csv
from drillgym.eval.diagnosis.validate import LogCheckError
from drillgym.eval.logs import read_episode_log


@pytest.fixture(scope="module")
def logged(tmp_path_factory):
    d = tmp_path_factory.mktemp("rtde")
    header, df = sim_log(d / "ep.parquet", controller="li2023", seed=3)
    return d, header, df


@pytest.fixture
def session(logged, tmp_path):
    _, header, df = logged
    return write_session(tmp_path / "session", header, df)


def test_the_recording_is_in_ur_rtdes_format(session):
    lines = (session / "rtde.csv").read_text().splitlines()
    names = lines[0].split(",")
    assert names[0] == "timestamp" and "actual_q_0" in names and "actual_q_5" in names and "actual_TCP_pose_5" in names
    assert not lines[0].endswith(",")
    first = lines[1].split(",")
    assert len(first) == len(names)
    assert all(len(v.split(".")[1]) == 6 for v in first if "." in v)  # std::fixed, setprecision(6)
    assert float(first[0]) == pytest.approx(RTDE_T0 + 1 / 125.0)
    assert list(read_rtde_csv(session / "rtde.csv").columns) == names


def test_import_reproduces_the_logged_episode(logged, session):
    _, _, df = logged
    header, frame = import_session(session)
    assert header["source"] == "real" and header["seed"] is None
    assert len(frame) == len(df)
    for col in ("ft_fx_n", "ft_fz_n", "ft_ty_nm", "cmd_dx_base_m", "cmd_feed_scale"):
        np.testing.assert_allclose(frame[col], df[col], atol=1e-6, err_msg=col)
    for col in [f"q{i}_rad" for i in range(6)] + ["tcp_x_base_m", "tcp_z_base_m"]:
        np.testing.assert_allclose(frame[col], df[col], atol=1.1e-6, err_msg=col)  # 6 decimals
    np.testing.assert_allclose(frame["tracker_y_base_m"], df["tracker_y_base_m"], atol=1e-6)
    np.testing.assert_array_equal(frame["step"], df["step"])
    np.testing.assert_allclose(frame["depth_cmd_m"], df["depth_cmd_m"], atol=2e-4)  # interpolated between commands
    ep = episode_from_log("session", header, frame)
    assert ep.repairs == []


def test_a_session_folder_is_read_by_the_diagnosis_loader(session):
    episodes, skipped = load_episodes(session.parent)
    assert skipped == [] and [e.name for e in episodes] == ["session"]


def test_import_rtde_cli_writes_a_real_schema_log(session, tmp_path):
    from drillgym.eval.cli import main

    assert main(["import-rtde", str(session), "--out", str(tmp_path / "out")]) == 0
    header, frame = read_episode_log(tmp_path / "out" / "session.parquet")
    assert header["source"] == "real" and not [c for c in frame.columns if c.startswith("sim_")]


def test_repeated_robot_states_are_dropped_and_reported(session):
    lines = (session / "rtde.csv").read_text().splitlines()
    lines.insert(5, lines[4])  # the recorder wrote the same state twice
    (session / "rtde.csv").write_text("\n".join(lines) + "\n")
    header, _ = import_session(session)
    assert header["run"]["repairs"] == ["rtde.csv: 1 repeated robot state(s) dropped"]


def test_tracker_in_millimetres_is_converted(logged, session):
    tr = pd.read_csv(session / "tracker.csv")
    tr = tr.rename(columns={"x_m": "x_mm", "y_m": "y_mm", "z_m": "z_mm"})
    tr[["x_mm", "y_mm", "z_mm"]] *= 1000.0
    tr.to_csv(session / "tracker.csv", index=False)
    _, frame = import_session(session)
    np.testing.assert_allclose(frame["tracker_x_base_m"], logged[2]["tracker_x_base_m"], atol=2e-6)


def test_millimetres_labelled_as_metres_are_caught(session):
    tr = pd.read_csv(session / "tracker.csv")
    tr[["x_m", "y_m", "z_m"]] *= 1000.0
    tr.to_csv(session / "tracker.csv", index=False)
    header, frame = import_session(session)
    with pytest.raises(LogCheckError, match="mm"):
        episode_from_log("s", header, frame)


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (
            lambda d: (d / "rtde.csv").write_text((d / "rtde.csv").read_text().replace("actual_q_3", "actual_qx_3")),
            "actual_q_3",
        ),
        (lambda d: _edit_header(d, lambda m: m["clock"].pop("rtde_timestamp_at_t0_s")), "rtde_timestamp_at_t0_s"),
        (lambda d: _drop_rtde_rows(d, 200, 230), "gap"),
        (lambda d: _edit_header(d, lambda m: m["clock"].update(rtde_timestamp_at_t0_s=RTDE_T0 + 30)), "cover"),
        (lambda d: _rename_ft(d, "fz_n", "fz"), "unit"),
    ],
)
def test_bad_sessions_raise_naming_the_problem(session, damage, message):
    damage(session)
    with pytest.raises(LogCheckError, match=message):
        import_session(session)


def test_lost_ft_samples_are_a_time_gap(session):
    ft = pd.read_csv(session / "ft.csv")
    ft.drop(index=range(100, 104)).to_csv(session / "ft.csv", index=False)
    header, frame = import_session(session)
    with pytest.raises(LogCheckError, match="time gap"):
        episode_from_log("s", header, frame)


def _edit_header(d, fn):
    meta = json.loads((d / "header.json").read_text())
    fn(meta)
    (d / "header.json").write_text(json.dumps(meta))


def _drop_rtde_rows(d, a, b):
    lines = (d / "rtde.csv").read_text().splitlines()
    (d / "rtde.csv").write_text("\n".join(lines[:a] + lines[b:]) + "\n")


def _rename_ft(d, old, new):
    ft = pd.read_csv(d / "ft.csv")
    ft.rename(columns={old: new}).to_csv(d / "ft.csv", index=False)


def test_import_rtde_says_a_missing_session_folder_does_not_exist(tmp_path, capsys):
    from drillgym.eval.cli import main

    missing, a_file = tmp_path / "nonexistent", tmp_path / "notes.txt"
    a_file.write_text("not a session")
    assert main(["import-rtde", str(missing), str(a_file), "--out", str(tmp_path / "logs")]) == 2
    err = capsys.readouterr().err
    assert f"session folder {missing} does not exist" in err and "header.json: missing" not in err
    assert "is a file; a session is a folder" in err
    assert not (tmp_path / "logs").exists()
