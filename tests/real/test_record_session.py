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
