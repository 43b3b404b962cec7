import dataclasses
import re

import gymnasium as gym
import numpy as np
import pandas as pd
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers.none import NoCompensation, NoCompensationConfig
from drillgym.controllers.registry import CONTROLLERS
from drillgym.envs.metrics import METRIC_NAMES
from drillgym.eval.bench import episode as bench_episode
from drillgym.eval.bench import jobs as bench_jobs
from drillgym.eval.bench.episode import EpisodeJob, run_job
from drillgym.eval.bench.jobs import controller_label, split_controller_specs
from drillgym.eval.bench.summary import SUMMARY_COLUMNS
from drillgym.eval.cli import main
from drillgym.eval.logs import read_episode_log


def test_paper_suite_writes_every_output_with_the_exact_summary_header(tmp_path, capsys):
    out = tmp_path / "bench"
    assert main(["bench", "--suite", "paper", "--controllers", "none,li2023", "--seeds", "2", "--out", str(out)]) == 0
    episodes = pd.read_csv(out / "episodes.csv")
    assert len(episodes) == 4
    assert list(episodes[["controller", "seed"]].itertuples(index=False, name=None)) == [
        ("li2023", 0),
        ("li2023", 1),
        ("none", 0),
        ("none", 1),
    ]
    for col in ("suite", "scenario", "beta_deg", "feed_mm_s", "bone", *METRIC_NAMES, "wall_time_s", "error"):
        assert col in episodes
    assert episodes["error"].isna().all()
    assert (out / "summary.csv").read_text().splitlines()[0] == ",".join(SUMMARY_COLUMNS)
    assert ",".join(SUMMARY_COLUMNS) == "suite,scenario,controller,metric,mean,ci_low,ci_high,n"
    summary = pd.read_csv(out / "summary.csv")
    assert len(summary) == 2 * len(METRIC_NAMES) and (summary["n"] == 2).all()
    md = (out / "summary.md").read_text()
    assert "Paired differences vs `none`" in md and "| paper | `li2023` | 2 |" in md
    assert (out / "paper_deviation_force.png").stat().st_size > 10_000
    for row in episodes.itertuples():
        header, df = read_episode_log(out / row.log)
        assert header["run"]["controller_spec"] == row.controller and header["seed"] == row.seed
        assert len(df) == 5 * row.steps
    assert "summary.md" in capsys.readouterr().out


def test_results_do_not_depend_on_the_number_of_workers(tmp_path):
    frames = []
    for k in (1, 2):
        out = tmp_path / f"w{k}"
        args = ["bench", "--controllers", "none,li2023", "--seeds", "2", "--out", str(out), "--workers", str(k)]
        assert main([*args, "--no-logs"]) == 0
        frames.append((out / "episodes.csv").read_text())
        assert not (out / "logs").exists()
    a, b = (pd.read_csv(pd.io.common.StringIO(t)).drop(columns="wall_time_s") for t in frames)
    pd.testing.assert_frame_equal(a, b)


@dataclasses.dataclass
class CrashConfig:
    after_steps: int = 30


class CrashingController(NoCompensation):
    """Raises mid-episode, like a controller bug or a cut-off run."""

    name = "crash"

    def __init__(self, config=None):
        super().__init__(NoCompensationConfig())
        self.config = config or CrashConfig()
        self.steps = 0

    def reset(self):
        self.steps = 0

    def act(self, obs):
        self.steps += 1
        if self.steps > self.config.after_steps:
            raise RuntimeError("controller exploded")
        return super().act(obs)


def test_an_episode_that_raises_keeps_its_partial_log_and_the_bench_goes_on(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(CONTROLLERS, "crash", (CrashingController, CrashConfig))
    out = tmp_path / "bench"
    code = main(["bench", "--controllers", "none,crash", "--seeds", "1", "--out", str(out)])
    assert code == 1
    assert "1 of 2 episodes failed" in capsys.readouterr().err
    episodes = pd.read_csv(out / "episodes.csv").set_index("controller")
    assert "controller exploded" in episodes.loc["crash", "error"]
    assert np.isnan(episodes.loc["crash", "deviation_mean_mm"])
    assert episodes.loc["none", "deviation_mean_mm"] > 0
    assert "controller exploded" in (out / "errors.log").read_text()
    log = out / episodes.loc["crash", "log"]
    assert not log.exists() and log.with_suffix("").is_dir()  # the directory of an unfinished log
    header, df = read_episode_log(log)
    assert df.attrs["partial"] and header["controller"]["name"] == "crash"
    assert len(df) == 150  # 30 steps: the process survived the exception, so every recorded sample was flushed


def test_killed_run_leaves_a_readable_partial_log(tmp_path):
    from drillgym.eval.logs import EpisodeLogger, build_header

    env = gym.make("drillgym/UR5BoneDrill-v1")
    path = tmp_path / "killed.parquet"
    logger = EpisodeLogger(env, path, build_header(env, None))
    logger.reset(seed=0)
    with pytest.raises(KeyboardInterrupt):
        for step in range(1000):
            logger.step(np.zeros(4, dtype=np.float32))
            if step == 45:
                raise KeyboardInterrupt  # the process dies here: nothing is closed or compacted
    header, df = read_episode_log(path)
    assert df.attrs["partial"] and len(df) == 200 and header["seed"] == 0
    np.testing.assert_array_equal(df.t_s, env.unwrapped.recorder.t_s[:200])
    env.close()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--controllers", "none,li2023:kq=1.0"], "kq"),
        (["--controllers", "none,pid"], "unknown controller 'pid'"),
        (["--controllers", "li2023:kp=fast"], "kp"),
        (["--controllers", "none,none"], "twice"),
        (["--seeds", "0"], "--seeds=0 must be >= 1"),
        (["--workers", "0"], "--workers=0 must be >= 1"),
        (["--suite", "marathon"], "unknown suite 'marathon'"),
    ],
)
def test_bad_arguments_are_reported_before_any_episode_runs(tmp_path, capsys, argv, message):
    out = tmp_path / "bench"
    assert main(["bench", "--out", str(out), *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_controller_specs_with_several_overrides_split_and_label_cleanly():
    specs = split_controller_specs("none, li2023:kp=1.0,ki=0.5,li2023")
    assert specs == ["none", "li2023:kp=1.0,ki=0.5", "li2023"]
    assert controller_label("li2023:kp=1.0,ki=0.5") == "li2023_kp-1.0_ki-0.5"
    assert controller_label("residual:runs/a b/model.zip") == "residual_runs_a_b_model.zip"
    with pytest.raises(ValueError, match="no controller name"):
        split_controller_specs("kp=1.0,none")


def test_a_scenario_the_env_rejects_becomes_an_error_row():
    row = run_job(EpisodeJob("paper", "bad", {"beta_deg": 80.0}, "none", 0))
    assert "beta_deg" in row["error"] and np.isnan(row["deviation_mean_mm"])
    assert bench_episode.run_job(EpisodeJob("paper", "paper", {}, "none", 0))["error"] == ""


def test_a_second_run_into_the_same_folder_needs_overwrite_and_then_leaves_no_stale_logs(tmp_path, capsys):
    out = tmp_path / "bench"
    base = ["bench", "--controllers", "none", "--seeds", "2", "--out", str(out)]
    assert main(base) == 0
    assert len(list((out / "logs").glob("*.parquet"))) == 2
    assert main(["bench", "--controllers", "none", "--seeds", "1", "--out", str(out)]) == 2
    assert "previous run" in capsys.readouterr().err
    assert len(list((out / "logs").glob("*.parquet"))) == 2  # nothing touched
    (out / "notes.txt").write_text("mine")
    assert main(["bench", "--controllers", "none", "--seeds", "1", "--out", str(out), "--overwrite"]) == 0
    logs = sorted(p.name for p in (out / "logs").glob("*.parquet"))
    assert logs == ["paper__paper__none__seed0.parquet"]
    assert (out / "notes.txt").read_text() == "mine"
    assert len(pd.read_csv(out / "episodes.csv")) == 1


def test_one_seed_reports_no_interval_and_counts_in_the_singular(tmp_path):
    out = tmp_path / "one"
    assert main(["bench", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", str(out)]) == 0
    text = (out / "summary.md").read_text()
    assert "1 episode: seed 0 " in text
    assert " [–] |" in text
    assert not re.search(r"\[([-\d.e+]+), \1\]", text), "a zero-width interval"


def interrupt_after(monkeypatch, k):
    """Make the in-process batch that holds the (k+1)-th episode raise KeyboardInterrupt (a Ctrl-C); count the episodes."""
    calls = []

    def run_batch(jobs):
        calls.extend(job.key for job in jobs)
        if len(calls) > k:
            raise KeyboardInterrupt
        return real_run_batch(jobs)

    real_run_batch = bench_episode.run_batch
    monkeypatch.setattr(bench_jobs, "run_batch", run_batch)  # where the pool calls it
    return calls


def read_text_columns(path):
    """episodes.csv as written (every cell as text), without the timing."""
    return pd.read_csv(path, dtype=str, keep_default_na=False).drop(columns="wall_time_s")


def test_an_interrupted_run_keeps_its_finished_episodes_and_resume_completes_it(tmp_path, monkeypatch, capsys):
    whole, out = tmp_path / "whole", tmp_path / "cut"
    args = ["bench", "--controllers", "none,li2023", "--seeds", "2"]
    assert main([*args, "--out", str(whole)]) == 0
    capsys.readouterr()

    calls = interrupt_after(monkeypatch, 2)  # the batch of li2023's two seeds is cut
    assert main([*args, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    episodes = pd.read_csv(out / "episodes.csv")
    assert len(episodes) == 2 and episodes["error"].isna().all()
    assert "episodes.csv keeps the 2 of 4 episodes that finished" in err and "drillgym bench: interrupted" in err
    resume = f"drillgym bench --suite paper --controllers none,li2023 --cell ideal --seeds 2 --out {out} --resume"
    assert resume in err
    assert not (out / "summary.md").exists()
    assert main([*args, "--out", str(out)]) == 2  # a plain rerun would replace it: refused
    assert "--resume to finish it" in capsys.readouterr().err

    calls.clear()
    assert main([*args, "--out", str(out), "--resume"]) == 0
    assert len(calls) == 2  # only the episodes that had not finished
    pd.testing.assert_frame_equal(read_text_columns(out / "episodes.csv"), read_text_columns(whole / "episodes.csv"))
    for name in ("summary.csv", "paired.csv"):
        assert (out / name).read_text() == (whole / name).read_text()
    assert sorted(p.name for p in (out / "logs").iterdir()) == sorted(p.name for p in (whole / "logs").iterdir())


def test_a_resumed_run_reruns_the_episodes_that_failed(tmp_path, monkeypatch):
    out = tmp_path / "bench"
    args = ["bench", "--controllers", "none", "--seeds", "2", "--no-logs", "--out", str(out)]
    real_run_batch = bench_episode.run_batch
    calls = []

    def flaky(jobs):
        rows = real_run_batch(jobs)
        first = not calls
        calls.extend(job.seed for job in jobs)
        return [
            {**r, "error": "RuntimeError: flaky", "traceback": "flaky"} if first and i == 1 else r
            for i, r in enumerate(rows)
        ]

    monkeypatch.setattr(bench_jobs, "run_batch", flaky)
    assert main(args) == 1
    assert (out / "errors.log").exists()
    assert main([*args, "--resume"]) == 0
    assert calls == [0, 1, 1]
    assert pd.read_csv(out / "episodes.csv")["error"].isna().all() and not (out / "errors.log").exists()


def test_resume_needs_a_previous_run_of_the_same_command(tmp_path, capsys):
    out = tmp_path / "bench"
    args = ["bench", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", str(out)]
    assert main([*args, "--resume"]) == 2
    assert "episodes.csv does not exist, so there is nothing to resume" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main([*args, "--resume", "--overwrite"])
    assert exit_.value.code == 2 and "not allowed with argument" in capsys.readouterr().err
    assert main(args) == 0
    capsys.readouterr()
    assert main(["bench", "--controllers", "none", "--seeds", "2", "--no-logs", "--out", str(out), "--resume"]) == 2
    assert "seeds 1 then, 2 now" in capsys.readouterr().err
    (out / "run.json").unlink()  # a run from before run.json: each episode is checked against the command
    assert main(["bench", "--controllers", "li2023", "--seeds", "1", "--no-logs", "--out", str(out), "--resume"]) == 2
    assert "holds an episode this command does not run (paper paper none seed 0)" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0  # already complete: only the report is written again
