"""The real-cell commands: ``drillgym run`` (against the emulator), ``drillgym emulate``, ``drillgym bench-rtde``."""

import json
import subprocess
import sys

import pytest
from real_cell import ONE_CELL_AT_A_TIME

from drillgym.envs.real.emulator.process import free_loopback_host, ports_free
from drillgym.eval.cli import main
from drillgym.eval.logs import read_episode_log

pytestmark = ONE_CELL_AT_A_TIME  # whole cells: one at a time (real_cell.py)

SHORT_PLAN = "feed_mm_s=3,depth_mm=3"
"""A 3 s hole (approach 1.4 s, feed 1.1 s, retract 0.6 s)."""


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_run_drills_logs_and_prints_the_measurable_metrics(start_emulator, tmp_path, capsys):
    emu = start_emulator(scenario={"feed_mm_s": 3.0, "depth_mm": 3.0})
    argv = ["run", "--robot", emu.host, "--tracker", f"udp:{emu.host}", "--scenario", SHORT_PLAN, "--yes"]
    argv += ["--max-gap-ms", "500"]  # a shared CI machine can stall the emulator for >100 ms
    assert main([*argv, "--controller", "li2023", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "lateral_force_max_n" in out and "tracker_deviation_mean_mm" in out and "measure the hole" in out
    results = json.loads((tmp_path / "metrics.json").read_text())
    assert results[0]["failure"] is None and results[0]["metrics"]["deviation_mean_mm"] is None
    assert results[0]["metrics"]["thrust_max_n"] > 1.0
    header, df = read_episode_log(tmp_path / results[0]["log"])
    assert header["source"] == "real" and header["controller"]["name"] == "li2023" and len(df) > 250
    assert header["scenario"]["feed_mm_s"] == 3.0 and header["run"]["robot"] == emu.host
    assert (tmp_path / "commands.jsonl").stat().st_size > 0


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_run_seeds_each_emulated_specimen_as_the_sim_does(start_emulator, tmp_path, capsys):
    import gymnasium as gym

    from drillgym.envs import SIM_ENV_ID

    scenario = {"feed_mm_s": 3.0, "depth_mm": 3.0}
    emu = start_emulator(seed=0, scenario=scenario)
    argv = ["run", "--robot", emu.host, "--scenario", SHORT_PLAN, "--yes", "--max-gap-ms", "500"]
    assert main([*argv, "--seed", "3", "--episodes", "2", "--out", str(tmp_path)]) == 0
    results = json.loads((tmp_path / "metrics.json").read_text())
    sim = gym.make(SIM_ENV_ID, **scenario)
    for k, seed in enumerate((3, 4)):
        header, _ = read_episode_log(tmp_path / results[k]["log"])
        specimen = header["run"]["emulator_specimen"]
        assert header["seed"] == seed and specimen["seed"] == seed and specimen["replaced_now"]
        _, info = sim.reset(seed=seed)
        assert specimen["hardness_factor"] == info["specimen_hardness"]  # the same specimen, bit for bit
    sim.close()


def test_run_asks_before_moving(start_emulator, tmp_path):
    emu = start_emulator()
    cmd = [sys.executable, "-m", "drillgym.eval.cli", "run", "--robot", emu.host, "--out", str(tmp_path)]
    proc = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "--yes" in proc.stderr and "nothing moved" in proc.stdout
    assert emu.status()["command_counts"] == {} and emu.status()["scripts_loaded"] == 0


def test_run_rejects_an_unknown_controller_before_connecting(tmp_path, capsys):
    """The robot address is a loopback one whose UR ports are free (so no controller, a URSim on this machine
    included, could answer there): the refusal comes from the arguments, not from a connection."""
    assert main(["run", "--robot", free_loopback_host(), "--controller", "pid9000", "--out", str(tmp_path)]) == 2
    assert "pid9000" in capsys.readouterr().err


def test_run_rejects_a_non_positive_timing_limit_before_connecting(tmp_path, capsys):
    """As above: an address no controller listens on."""
    assert main(["run", "--robot", free_loopback_host(), "--max-gap-ms", "0", "--out", str(tmp_path)]) == 2
    assert "max_cycle_gap_s=0.0" in capsys.readouterr().err


def test_emulate_serves_and_exits_by_itself(capsys):
    host = free_loopback_host()
    assert main(["emulate", "--host", host, "--max-lifetime-s", "0.5", "--scenario", "beta_deg=20"]) == 0
    assert capsys.readouterr().out.startswith("READY ") and ports_free(host)


@pytest.mark.realtime  # streams to the emulator in real time: run alone (see the Makefile)
def test_bench_rtde_reports_missed_cycles_and_latency(capsys):
    assert main(["bench-rtde", "--seconds", "2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["cycles"] == 250 and result["missed_cycle_rate"] < 0.05
    assert result["latency_samples"] > 200
    assert 0.0 < result["command_to_state_latency"]["median_ms"] < 20.0
