"""The benchmark's batches: episodes of one (scenario, controller, cell) on the batched engine, as on the single env.

``run_batch`` must give the rows and the logs ``run_job`` gives episode by episode (timing and the logs' creation
time aside), bit for bit; fall back to the single env for cells the compiled step does not run and for a batch that
raises; and ``batches`` must group and split the grid as documented.
"""

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.bench import episode as bench_episode
from drillgym.eval.bench.episode import BATCH_MAX, EpisodeJob, run_batch, run_job
from drillgym.eval.bench.jobs import batches
from drillgym.eval.logs.reader import read_episode_log


def _jobs(controller: str, seeds: list[int], out=None, effects: str = "", kwargs=None) -> list[EpisodeJob]:
    jobs = []
    for s in seeds:
        name = f"{controller}_{s}.parquet"
        path = None if out is None else out / name
        jobs.append(EpisodeJob("paper", "paper", kwargs or {}, controller, s, path, name if out else "", effects))
    return jobs


def _without_timing(row: dict) -> dict:
    return {k: v for k, v in row.items() if k != "wall_time_s"}


def test_a_batch_gives_the_rows_and_logs_of_its_episodes_run_one_by_one(tmp_path):
    spec = "joint_friction:coulomb_rad=4e-4,viscous_s=0.005"
    batched = run_batch(_jobs("zhang2005", [2, 0, 1], tmp_path / "b", spec))
    single = [run_job(j) for j in _jobs("zhang2005", [2, 0, 1], tmp_path / "s", spec)]
    assert [_without_timing(r) for r in batched] == [_without_timing(r) for r in single]
    assert all(r["error"] == "" and r["steps"] > 100 for r in batched)
    for s in (2, 0, 1):
        hb, db = read_episode_log(tmp_path / "b" / f"zhang2005_{s}.parquet")
        hs, ds = read_episode_log(tmp_path / "s" / f"zhang2005_{s}.parquet")
        hb.pop("created_utc"), hs.pop("created_utc")
        assert hb == hs
        pd.testing.assert_frame_equal(db, ds, check_exact=True)


def test_episodes_with_cells_of_their_own_batch_together_with_the_rows_and_logs_of_one_by_one(tmp_path):
    """A cell drawn per episode (the robustness suite's ``*_drawn``): one batch, each slot in its own cell."""
    cells = ["joint_friction:coulomb_rad=3e-4", "", "latency:extra_latency_s=0.06+joint_backlash:play_rad=5e-4"]
    jobs_b = [j for k, c in enumerate(cells) for j in _jobs("li2023_tuned", [k], tmp_path / "b", c)]
    jobs_s = [j for k, c in enumerate(cells) for j in _jobs("li2023_tuned", [k], tmp_path / "s", c)]
    assert len(batches(jobs_b)) == 1
    batched = run_batch(jobs_b)
    single = [run_job(j) for j in jobs_s]
    assert [_without_timing(r) for r in batched] == [_without_timing(r) for r in single]
    assert len({r["deviation_mean_mm"] for r in batched}) == 3
    for k in range(3):
        hb, db = read_episode_log(tmp_path / "b" / f"li2023_tuned_{k}.parquet")
        hs, ds = read_episode_log(tmp_path / "s" / f"li2023_tuned_{k}.parquet")
        hb.pop("created_utc"), hs.pop("created_utc")
        assert hb == hs and hb["run"]["effects"] == cells[k]
        pd.testing.assert_frame_equal(db, ds, check_exact=True)


def test_a_cell_with_effects_the_compiled_step_does_not_run_goes_episode_by_episode(monkeypatch):
    ran = []
    monkeypatch.setattr(bench_episode, "run_job", lambda job: ran.append(job.seed) or {"seed": job.seed})
    rows = run_batch(_jobs("none", [0, 1], effects="servo_deadband:band_m=1e-4"))
    assert ran == [0, 1] and [r["seed"] for r in rows] == [0, 1]


def test_a_batch_that_raises_runs_its_episodes_one_by_one_so_each_error_is_its_own(monkeypatch):
    def boom(jobs):
        raise RuntimeError("batch failed")

    monkeypatch.setattr(bench_episode, "_run_batched", boom)
    rows = run_batch(_jobs("none", [0], kwargs={"beta_deg": 80.0}) + _jobs("none", [1], kwargs={"beta_deg": 80.0}))
    assert all("beta_deg" in r["error"] for r in rows)  # the single env's own error, per episode


def test_jobs_of_mixed_batches_are_refused():
    with pytest.raises(ValueError, match="one"):
        run_batch(_jobs("none", [0]) + _jobs("li2023", [0]))


def test_batches_group_by_controller_and_uncompiled_cell_and_split_for_the_workers():
    grid = (
        _jobs("none", list(range(10)))
        + _jobs("li2023", list(range(10)))
        + _jobs("none", [0, 1], effects="servo_deadband:band_m=1e-4")
        + _jobs("none", [10, 11], effects="latency:extra_latency_s=0.1")  # compiled: each slot runs its own cell
    )
    one = batches(grid, workers=1)
    assert [(b[0].controller, b[0].effects, len(b)) for b in one] == [
        ("none", "", 12),
        ("li2023", "", 10),
        ("none", "servo_deadband:band_m=1e-4", 2),
    ]
    assert [len(b) for b in batches(grid, workers=4)] == [6, 6, 6, 4, 2]  # at most 24 / 4 -> 6 per batch
    assert max(len(b) for b in batches(_jobs("none", list(range(200))), workers=1)) == BATCH_MAX


@pytest.mark.parametrize("compiled", [True, False])
def test_a_batch_cut_short_leaves_each_log_readable_up_to_its_last_logged_step(tmp_path, monkeypatch, compiled):
    """A controller that raises at its fourth compensation point (step 36): every open log keeps the 36 steps logged,
    as the single env's logger does when an episode raises (then the batch reruns episode by episode); in the
    compiled loop and in the Python one."""
    import drillgym.controllers.rollout as rollout
    from drillgym.controllers.li2023 import Li2023Controller
    from drillgym.eval.logs.batch_logger import BatchLogger

    kept = []
    real = BatchLogger.abandon

    def abandon(self):
        real(self)
        kept.append([read_episode_log(j.log_path.with_suffix(""), allow_partial=True)[1] for j in jobs])

    monkeypatch.setattr(BatchLogger, "abandon", abandon)
    calls = {"n": 0}
    real_point = Li2023Controller._compensation_point

    def point(self, obs, t):
        calls["n"] += 1
        if calls["n"] == 4:
            raise RuntimeError("controller exploded")
        return real_point(self, obs, t)

    monkeypatch.setattr(Li2023Controller, "_compensation_point", point)
    real_run_batch = rollout.run_batch
    monkeypatch.setattr(rollout, "run_batch", lambda *a, **k: real_run_batch(*a, **{**k, "compiled": compiled}))
    jobs = _jobs("li2023", [0, 1], tmp_path)
    with pytest.raises(RuntimeError, match="exploded"):
        bench_episode._run_batched(jobs)
    assert [len(df) for df in kept[0]] == [180, 180]  # 36 steps of 5 samples each
    assert (kept[0][0]["step"].to_numpy() == np.repeat(np.arange(36), 5)).all()


@pytest.mark.parametrize("clock_step_s", [0.0, 10.0])
@pytest.mark.parametrize("seeds", [[0], [0, 1]])  # one episode steps in Python; two, in the compiled loop
def test_a_batched_log_writes_a_part_once_its_rows_and_its_seconds_are_due(tmp_path, monkeypatch, clock_step_s, seeds):
    """A part waits for 100 rows and one second since the log's last part: on a frozen clock one part (the episode's
    end), on a clock of 10 s a call parts of at least 100 rows (every 20 steps in Python, every 24 in the compiled
    loop, which hands its rows over every 12 steps); the compacted log is the same either way."""
    from drillgym.eval.logs import batch_logger
    from drillgym.eval.logs.writer import EpisodeLogWriter

    clock = {"t": 0.0}

    def monotonic():
        clock["t"] += clock_step_s
        return clock["t"]

    written: dict = {}
    real_flush = EpisodeLogWriter.flush

    def flush(self):
        if self._buffered:
            written.setdefault(self.path.name, []).append(self._buffered)
        real_flush(self)

    monkeypatch.setattr(batch_logger.time, "monotonic", monotonic)
    monkeypatch.setattr(EpisodeLogWriter, "flush", flush)
    rows = bench_episode._run_batched(_jobs("li2023", seeds, tmp_path))
    for seed, row in zip(seeds, rows, strict=True):
        parts = written[f"li2023_{seed}.parquet"]
        assert sum(parts) == 5 * row.steps and row.steps > 200
        if clock_step_s == 0.0:
            assert len(parts) == 1
        else:
            assert all(n >= 100 for n in parts[:-1]) and len(parts) >= row.steps // 24
        _, frames = read_episode_log(tmp_path / f"li2023_{seed}.parquet")
        assert (frames["step"].to_numpy() == np.repeat(np.arange(row.steps), 5)).all()
