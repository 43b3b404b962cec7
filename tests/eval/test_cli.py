import json

from drillgym.eval.cli import COMMANDS, main


def test_help_lists_every_command(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    for name in COMMANDS:
        assert name in out


def test_unknown_command_is_an_error_naming_it(capsys):
    try:
        main(["drill-faster"])
    except SystemExit as e:
        assert e.code == 2
    assert "drill-faster" in capsys.readouterr().err


def test_bench_speed_json_reports_a_real_time_factor(capsys):
    argv = ["--runs", "1", "--json", "--batch-sizes", "1,4", "--batch-seconds", "0.3", "--rollout-seeds", "2"]
    argv += ["--schedule-holes", "2", "--threads", "2"]
    assert main(["bench-speed", *argv, "--rollout-controllers", "none"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["real_time_factor_median"] > 0
    assert result["env_step_per_bare_pybullet_step_median"] > 0
    assert len(result["env_step_per_bare_pybullet_step_runs"]) == 1
    assert result["bare_pybullet_step_us_median"] > 0 and result["construct_s"] > 0
    assert result["episode_sim_s"] > 10
    assert result["peak_rss_mib"] > 0
    batched = result["batched"]
    assert batched["single_env_episodes_per_s_median"] > 0
    assert set(batched["batched"]) == {"1", "4", "1/2", "4/2"}  # each size on one thread and on two
    assert batched["batched"]["4/2"]["threads"] == 2 and batched["batched"]["4"]["threads"] == 1
    assert all(b["episodes_per_s_median"] > 0 for b in batched["batched"].values())
    for b in batched["batched"].values():  # the compiled step is part of the step: its ceiling lies above the speed-up
        assert b["kernel_us_per_episode_step_median"] > 0
        assert b["kernel_only_speedup_ceiling_median"] > b["speedup_over_single_median"]
    rollouts = result["rollouts"]
    assert rollouts["seeds"] == 2 and len(rollouts["none"]["speedup_runs"]) == 3
    assert rollouts["none"]["batched_episodes_per_s_median"] > 0
    assert len(rollouts["none"]["compiled_loop_speedup_runs"]) == 3  # none runs the Python loop both ways
    assert rollouts["none"]["python_loop_episodes_per_s_median"] > 0
    schedule = result["schedule"]  # (the rewards were checked equal while measuring)
    assert schedule["holes"] == 2 and len(schedule["speedup_runs"]) == 3 and schedule["batched_holes_per_s_median"] > 0


def test_demo_runs_the_reproduction_and_says_where_the_results_are(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path), "--quick"]) == 0
    out = capsys.readouterr().out
    assert "mean tip deviation, uncompensated" in out and str(tmp_path.resolve()) in out
    assert (tmp_path / "report.md").exists()


def test_no_command_prints_pybullets_build_line(tmp_path):
    import subprocess
    import sys

    code = "from drillgym.eval.cli import main; main(['diagnose', '--help'])"
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "usage: drillgym diagnose" in proc.stdout
    assert "build time" not in proc.stdout + proc.stderr


def test_progress_bars_stay_out_of_a_log_that_is_not_a_terminal(tmp_path, capsys):
    assert main(["bench", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "\r" not in captured.out + captured.err


def test_bench_speed_times_a_diagnosis_of_a_withheld_effect_reality(capsys):
    from drillgym.eval.perf.diagnosis_speed import diagnosis_time

    result = diagnosis_time(episodes=6, workers=1, runs=1)
    assert result["episodes"] == 6 and len(result["runs_s"]) == 1 and result["median_s"] > 0
    assert result["reality"].startswith("stribeck_friction")
    assert main(["bench-speed", "--diagnosis-episodes", "3"]) == 2
    assert "--diagnosis-episodes must be 0 (skipped) or >= 6" in capsys.readouterr().err
