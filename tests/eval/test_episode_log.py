import datetime as dt
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pyarrow as pa
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.eval.logs import (
    COLUMN_NAMES,
    LOG_SCHEMA_VERSION,
    SIM_COLUMNS,
    EpisodeLogError,
    EpisodeLogger,
    EpisodeLogWriter,
    build_header,
    read_episode_log,
)
from drillgym.eval.logs.writer import schema_for

ENV_ID = "drillgym/UR5BoneDrill-v1"
ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def env():
    e = gym.make(ENV_ID)
    yield e
    e.close()


def run_logged(env, path, controller_spec="li2023", seed=0, max_steps=None, **logger_kwargs):
    """Run (part of) an episode through an EpisodeLogger; returns (logger, steps, recorder copy)."""
    controller = make_controller(controller_spec)
    logger = EpisodeLogger(env, path, build_header(env, controller.describe()), **logger_kwargs)
    obs, _ = logger.reset(seed=seed)
    controller.set_plan(env.unwrapped.plan)
    start, steps = True, 0
    while max_steps is None or steps < max_steps:
        action, _ = controller.predict(obs, episode_start=np.array([start]))
        obs, _, terminated, truncated, _ = logger.step(action)
        start, steps = False, steps + 1
        if terminated or truncated:
            break
    return logger, steps


def test_round_trip_keeps_every_sample_and_the_header(env, tmp_path):
    path = tmp_path / "ep.parquet"
    logger, steps = run_logged(env, path, seed=3)
    rec = env.unwrapped.recorder
    assert path.is_file() and not (tmp_path / "ep").exists()  # compacted at episode end, directory gone
    header, df = read_episode_log(path)
    assert list(df.columns) == list(COLUMN_NAMES)
    assert len(df) == len(rec.t_s) == 5 * steps
    assert not df.attrs["partial"]
    np.testing.assert_array_equal(df.t_s, rec.t_s)
    np.testing.assert_array_equal(df[["ft_fx_n", "ft_fy_n", "ft_fz_n"]].to_numpy(), np.asarray(rec.ft_force_n))
    np.testing.assert_array_equal(df[["ft_tx_nm", "ft_ty_nm", "ft_tz_nm"]].to_numpy(), np.asarray(rec.ft_torque_nm))
    np.testing.assert_array_equal(df.sim_deviation_m, rec.deviation_m)
    np.testing.assert_allclose(np.hypot(df.sim_tip_x_task_m, df.sim_tip_y_task_m), rec.deviation_m, atol=1e-15)
    np.testing.assert_array_equal(df.sim_stage, rec.stage)
    np.testing.assert_array_equal(df.phase, rec.phase)
    np.testing.assert_array_equal(df.step, np.repeat(np.arange(steps), 5))
    assert header["seed"] == 3 and header["controller"]["name"] == "li2023"
    assert header == logger.header
    logger.close_log()  # idempotent after the automatic compaction


def test_step_channels_match_the_observation_and_action(env, tmp_path):
    path = tmp_path / "ep.parquet"
    logger = EpisodeLogger(env, path, build_header(env, None))
    logger.reset(seed=1)
    action = np.array([0.5, -0.25, 0.0, 0.5], dtype=np.float32)
    obs, *_ = logger.step(action)
    logger.close_log()
    _, df = read_episode_log(path)
    assert len(df) == 5
    row = df.iloc[-1]
    assert row.cmd_dx_base_m == pytest.approx(1e-3) and row.cmd_dy_base_m == pytest.approx(-0.5e-3)
    assert row.cmd_feed_scale == pytest.approx(2.0)
    np.testing.assert_allclose(df.iloc[0][[f"q{i}_rad" for i in range(6)]].astype(float), obs["q_rad"], rtol=1e-6)
    np.testing.assert_allclose(
        row[["tcp_x_base_m", "tcp_y_base_m", "tcp_z_base_m"]].astype(float), env.unwrapped.rtde_tcp_base
    )
    assert bool(row.tracker_valid)


def test_crash_leaves_a_directory_readable_up_to_the_last_flush(env, tmp_path):
    path = tmp_path / "crashed.parquet"
    logger, steps = run_logged(env, path, max_steps=50)  # 250 samples; flushed at 100 and 200; never closed
    assert steps == 50
    assert not path.exists()
    directory = tmp_path / "crashed"
    assert sorted(p.name for p in directory.iterdir()) == ["header.json", "part-00000.arrow", "part-00001.arrow"]
    rec = env.unwrapped.recorder
    for name in (path, directory, str(directory)):  # the file name falls back to the directory
        header, df = read_episode_log(name)
        assert df.attrs["partial"]
        assert len(df) == 200
        np.testing.assert_array_equal(df.t_s, rec.t_s[:200])
        assert header["controller"]["name"] == "li2023"
    del logger


def test_corrupt_part_is_named_and_allow_partial_returns_the_good_rows(env, tmp_path):
    path = tmp_path / "bad.parquet"
    run_logged(env, path, max_steps=60)  # 300 samples: parts 0, 1, 2
    part = tmp_path / "bad" / "part-00001.arrow"
    data = part.read_bytes()
    part.write_bytes(data[: len(data) // 2])  # truncated: footer gone
    with pytest.raises(EpisodeLogError, match=re.escape("part-00001.arrow")):
        read_episode_log(path)
    with pytest.warns(RuntimeWarning, match="part-00001"):
        _, df = read_episode_log(path, allow_partial=True)
    rec = env.unwrapped.recorder
    assert len(df) == 200
    np.testing.assert_array_equal(df.t_s, np.concatenate([rec.t_s[:100], rec.t_s[200:300]]))
    assert df.attrs["skipped_parts"] == ["part-00001.arrow"]


def test_a_directory_left_with_parquet_parts_by_an_earlier_version_is_still_read(env, tmp_path):
    import pyarrow.parquet as pq

    path = tmp_path / "old.parquet"
    run_logged(env, path, max_steps=50)  # parts 0 and 1 as Arrow IPC files
    directory = tmp_path / "old"
    first = directory / "part-00000.arrow"
    with pa.memory_map(str(first)) as source:
        pq.write_table(pa.ipc.open_file(source).read_all(), directory / "part-00000.parquet")
    first.unlink()
    _, df = read_episode_log(path)
    rec = env.unwrapped.recorder
    np.testing.assert_array_equal(df.t_s, rec.t_s[:200])


def test_missing_log_and_foreign_parquet_give_clear_errors(tmp_path):
    with pytest.raises(EpisodeLogError, match="no episode log"):
        read_episode_log(tmp_path / "nothing.parquet")
    import pandas as pd

    pd.DataFrame({"a": [1]}).to_parquet(tmp_path / "foreign.parquet")
    with pytest.raises(EpisodeLogError, match="not an episode log"):
        read_episode_log(tmp_path / "foreign.parquet")


def test_header_holds_versions_controller_config_and_provenance(env):
    controller = make_controller("li2023:kp=1.0")
    header = build_header(env, controller.describe(), seed=4, extra={"suite": "paper"})
    assert header["schema_version"] == LOG_SCHEMA_VERSION
    assert header["source"] == "sim"
    assert header["env_id"] == ENV_ID
    assert header["seed"] == 4
    assert header["scenario"] == env.unwrapped.scenario.to_dict()
    assert header["controller"]["name"] == "li2023"
    assert header["controller"]["config"]["kp"] == 1.0
    for pkg in ("drillgym", "numpy", "gymnasium", "pybullet", "pin", "stable-baselines3", "python"):
        assert header["versions"][pkg], pkg
    created = dt.datetime.fromisoformat(header["created_utc"])
    assert created.utcoffset() == dt.timedelta(0)
    assert np.asarray(header["plan"]["T_base_task"]).shape == (4, 4)
    assert header["run"] == {"suite": "paper"}


def test_a_logger_logs_one_episode_and_never_overwrites_by_default(env, tmp_path):
    path = tmp_path / "one.parquet"
    logger, _ = run_logged(env, path, max_steps=2)
    with pytest.raises(RuntimeError, match="one episode"):
        logger.reset(seed=1)
    with pytest.raises(FileExistsError):
        EpisodeLogWriter(path, build_header(env, None))
    EpisodeLogWriter(path, build_header(env, None), overwrite=True).close()
    assert read_episode_log(path)[1].empty


def test_privileged_columns_are_exactly_the_sim_prefixed_ones_and_real_logs_lack_them():
    assert set(SIM_COLUMNS) == {
        "sim_tip_x_task_m",
        "sim_tip_y_task_m",
        "sim_tip_z_task_m",
        "sim_stage",
        "sim_deviation_m",
    }
    real = schema_for("real").names
    assert not set(real) & set(SIM_COLUMNS)
    assert set(real) | set(SIM_COLUMNS) == set(COLUMN_NAMES)


def test_schema_doc_lists_every_column():
    doc = (ROOT / "docs" / "log_schema.md").read_text()
    for name in COLUMN_NAMES:
        if not re.fullmatch(r"q[1-4]_rad", name):  # written as q0_rad … q5_rad
            assert f"`{name}`" in doc, name
