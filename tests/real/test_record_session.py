"""The generator of the shipped recording session: a hole on an emulator, recorded by ur_rtde, imported."""

from __future__ import annotations

import pytest

from drillgym.eval.diagnosis.rtde_import import import_session
from drillgym.eval.real.record_session import record_emulator_session


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_a_recorded_emulator_session_imports(tmp_path):
    out = record_emulator_session(tmp_path / "session", log_path=tmp_path / "env_log.parquet")
    header, frame = import_session(out)
    assert header["run"]["recorded_by"].endswith("record_emulator_session")
    assert 2.0 < frame["t_s"].iloc[-1] < 6.0 and frame["tracker_valid"].all()
    assert (tmp_path / "env_log.parquet").is_file() and not (out / "episode.parquet").exists()


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_run_record_rtde_writes_a_session_that_imports(start_emulator, tmp_path):
    from drillgym.eval.cli import main
    from drillgym.eval.logs import read_episode_log

    emu = start_emulator(scenario={"feed_mm_s": 3.0, "depth_mm": 3.0})
    argv = ["run", "--robot", emu.host, "--tracker", f"udp:{emu.host}", "--scenario", "feed_mm_s=3,depth_mm=3"]
    argv += ["--yes", "--max-gap-ms", "500", "--record-rtde", "--out", str(tmp_path)]
    assert main(argv) == 0
    session = tmp_path / "rtde" / "real__li2023__ep0"
    assert (session / "rtde.csv").read_text().startswith("timestamp,actual_q_0,")
    header, frame = import_session(session)
    _, env_log = read_episode_log(tmp_path / "logs" / "real__li2023__ep0.parquet")
    assert len(frame) == len(env_log) and header["run"]["robot"] == emu.host
    for col in ("tcp_x_base_m", "tcp_z_base_m"):  # the robot states land on the steps the env logged them in
        assert abs(frame[col] - env_log[col]).max() < 5e-4, col
