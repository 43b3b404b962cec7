"""`drillgym bench --ray`: same episodes as a local run, streamed outputs, a killed worker's episode retried."""

import os
import signal

import pandas as pd
import pytest

from drillgym.eval.bench.episode import EpisodeJob, run_job
from drillgym.eval.cli import main
from drillgym.eval.logs import read_episode_log
from drillgym.eval.scale.sink import StreamingSink


def _jobs(out, controllers=("none", "li2023"), seeds=2):
    jobs = []
    for spec in controllers:
        for seed in range(seeds):
            name = f"logs/paper__paper__{spec}__seed{seed}.parquet"
            jobs.append(EpisodeJob("paper", "paper", {}, spec, seed, out / name, name))
    return jobs


def _episodes(path):
    return pd.read_csv(path).drop(columns="wall_time_s")


def test_ray_and_local_runs_give_identical_outputs(tmp_path, ray_local):
    args = ["bench", "--suite", "paper", "--controllers", "none,li2023,li2023:kp=1.0", "--seeds", "2"]
    assert main([*args, "--out", str(tmp_path / "local")]) == 0
    assert main([*args, "--out", str(tmp_path / "ray"), "--ray"]) == 0
    local, remote = tmp_path / "local", tmp_path / "ray"
    pd.testing.assert_frame_equal(_episodes(local / "episodes.csv"), _episodes(remote / "episodes.csv"))
    for name in ("summary.csv", "paired.csv"):
        assert (local / name).read_text() == (remote / name).read_text(), name
    episodes = pd.read_csv(remote / "episodes.csv")
    assert len(episodes) == 6 and episodes["error"].isna().all()
    for log in episodes["log"]:
        header_l, df_l = read_episode_log(local / log)
        header_r, df_r = read_episode_log(remote / log)
        pd.testing.assert_frame_equal(df_l, df_r)
        assert {**header_l, "created_utc": None} == {**header_r, "created_utc": None}
    assert not list((remote / "logs").glob("*.tmp")) and not [p for p in (remote / "logs").iterdir() if p.is_dir()]


@pytest.mark.parametrize("chunk_size", [1, 2])
def test_a_worker_killed_mid_episode_is_retried_and_nothing_is_lost(tmp_path, ray_local, chunk_size):
    from drillgym.eval.scale.bench_ray import _scratch, run_jobs_ray

    marker = tmp_path / "killed"
    victim = ("li2023", 1)

    def kill_once(job):
        """Kill this worker process 150 steps into the victim's first attempt (after several log flushes)."""
        if (job.controller, job.seed) == victim and not marker.exists():
            from drillgym.eval.bench import episode as bench_episode

            marker.write_text(str(os.getpid()))
            real = bench_episode.run_controller_episode

            def dying(env, controller, seed):
                step, count = env.step, [0]

                def counted(action):
                    count[0] += 1
                    if count[0] == 150:
                        os.kill(os.getpid(), signal.SIGKILL)
                    return step(action)

                env.step = counted
                return real(env, controller, seed)

            bench_episode.run_controller_episode = dying
        return run_job(job)

    out = tmp_path / "ray"
    jobs = _jobs(out)
    result = run_jobs_ray(jobs, out, runner=kill_once, chunk_size=chunk_size)  # 2: the chunk is re-run whole
    assert marker.exists()  # the victim's worker did die
    expected = sorted((run_job(j) for j in _jobs(tmp_path / "local")), key=lambda r: (r["controller"], r["seed"]))
    got = sorted(result.rows, key=lambda r: (r["controller"], r["seed"]))
    assert [r["error"] for r in got] == [""] * 4
    drop = ("wall_time_s",)
    assert [{k: v for k, v in r.items() if k not in drop} for r in got] == [
        {k: v for k, v in r.items() if k not in drop} for r in expected
    ]
    streamed = pd.read_csv(out / "episodes.csv")  # written row by row as episodes completed
    assert len(streamed) == 4 and set(streamed["seed"]) == {0, 1}
    for job in jobs:
        header, df = read_episode_log(job.log_path)
        assert not df.attrs["partial"] and header["seed"] == job.seed
        assert not _scratch(job).exists()


def test_a_worker_that_dies_past_its_retries_becomes_an_error_row(tmp_path, ray_local):
    from drillgym.eval.scale.bench_ray import run_jobs_ray

    def always_die(job):
        if job.seed == 0:
            os.kill(os.getpid(), signal.SIGKILL)
        return run_job(job)

    out = tmp_path / "ray"
    rows = run_jobs_ray(_jobs(out, ("none",)), out, runner=always_die, max_retries=0).rows
    by_seed = {r["seed"]: r for r in rows}
    assert "worker failed" in by_seed[0]["error"] and by_seed[1]["error"] == ""
    assert (out / by_seed[1]["log"]).exists() and not (out / "logs/paper__paper__none__seed0.parquet").exists()


def test_chunks_cover_the_grid_with_about_four_tasks_per_cpu():
    from drillgym.eval.scale.bench_ray import chunk_size_for

    assert chunk_size_for(4, 2) == 1 and chunk_size_for(40, 2) == 5 and chunk_size_for(10_000, 2) == 8
    assert chunk_size_for(40, 64) == 1


def test_the_sink_appends_rows_and_logs_as_they_arrive(tmp_path):
    out = tmp_path / "bench"
    (out / "logs" / "a").mkdir(parents=True)  # a crashed run's partial log of the same name
    sink = StreamingSink(out, [("paper", "paper", "none")], refresh_s=0.0)
    row = run_job(EpisodeJob("paper", "paper", {}, "none", 0))
    sink.add({**row, "log": "logs/a.parquet"}, {"logs/a.parquet": b"PAR1"})
    assert len(pd.read_csv(out / "episodes.csv")) == 1 and (out / "logs/a.parquet").read_bytes() == b"PAR1"
    assert not (out / "logs" / "a").exists()
    sink.add({**row, "seed": 1, "log": ""})
    assert list(pd.read_csv(out / "episodes.csv")["seed"]) == [0, 1]
    summary = pd.read_csv(out / "summary.csv")
    assert (summary["n"] == 2).any()


def test_an_unreachable_cluster_is_a_clear_error(tmp_path, capsys):
    pytest.importorskip("ray")
    assert main(["bench", "--seeds", "1", "--out", str(tmp_path / "b"), "--address", "127.0.0.1:1"]) == 2
    assert "cannot connect to the Ray cluster" in capsys.readouterr().err


def test_a_worker_on_another_node_ships_the_log_bytes_to_the_driver(tmp_path):
    pytest.importorskip("ray")
    from drillgym.eval.scale.bench_ray import _scratch, run_episode_task

    name = "logs/paper__paper__li2023__seed0.parquet"
    job = EpisodeJob("paper", "paper", {}, "li2023", 0, tmp_path / "remote" / name, name)
    row, files = run_episode_task(job)  # no driver node given: as on a node other than the driver's
    assert list(files) == [name] and not (tmp_path / "remote").exists() and not _scratch(job).exists()
    sink = StreamingSink(tmp_path / "driver", [("paper", "paper", "li2023")])
    sink.add(row, files)
    local = tmp_path / "local" / name
    run_job(EpisodeJob("paper", "paper", {}, "li2023", 0, local, name))
    pd.testing.assert_frame_equal(read_episode_log(tmp_path / "driver" / name)[1], read_episode_log(local)[1])
