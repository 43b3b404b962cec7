"""Whole episodes through drillgym/UR5BoneDrillReal-v1 against the emulator, with the real ur_rtde client,
compared with the pure simulation of the same scenario and specimen.

The emulator draws the specimen from the seed like the sim, but its sensor noise is its own draw, and a
closed-loop compensator turns noise into a different entry: li2023's first compensation points amplify the
force and TCP noise of the approach (KP = 4), so the entry skid depends on the noise draw. On seed 0's specimen
the sim alone, under 12 noise draws, gives a maximum true deviation of 0.235-0.275 mm (SD 0.013 mm) and a stable
lateral force of 0.195-0.217 N (SD 0.0065 N); the plain seed-0 run (0.2745 mm) is the largest of the 12. So one
emulated run is compared with the sim's *distribution* on that specimen (``reset(options={"specimen_seed": 0})``
over SIM_NOISE_DRAWS noise seeds): it must lie in the sims' prediction interval at a family-wise level of
1 - 1e-4 (FALSE_FAILURE_RATE, Bonferroni over the 8 metrics), or within the real pipeline's timing allowance
(LI2023_TOL) of their mean, whichever is wider. The allowance: the sim applies each
action after exactly 14 ms on a fixed grid, the emulator after the real pipeline (servo process 0-8 ms + controller
cycle 0-8 ms + physics update 0-10 ms) with jitter; constant latencies from 4 to 22 ms move the sim's metrics by
< 1 % (docs/deployment.md §7). What once moved them far more was the servo loop's path clock: counted from the
stream's first cycle, the path lagged the agent's steps by the servo process's start (up to 124 ms under load), and
li2023's entry peak force, which depends on where its 600 ms grid meets the bone, rose to +30 %; the path now runs
on the episode's clock (tests/real/test_servo_command_gaps.py).
A residual policy also sets the feed, and the step-level one's (li2023_sac) bursts of slow feed at the entry amplify the
pipeline's timing: its entry (true deviation, peak force, drilling time) varies from run to run through the
emulator far beyond what the sim shows under its own noise draws or any constant latency (see RESIDUAL_TOL). Its
test compares only thrust and tracker deviation with the sim, and checks that the policy compensates and slows
the feed as in sim.
"""

import glob
import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from real_cell import CI_LIMITS, ONE_CELL_AT_A_TIME, make_real_env, run_steps
from scipy import stats

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.envs.real.emulator.process import free_loopback_host
from drillgym.envs.real.metrics import cell_metrics
from drillgym.envs.real.robot_link import LinkError
from drillgym.eval.logs import EpisodeLogger, build_header, read_episode_log
from drillgym.eval.logs.writer import schema_for

pytestmark = [pytest.mark.realtime, ONE_CELL_AT_A_TIME]  # timing-sensitive; whole cells one at a time (real_cell.py)

ROOT = Path(__file__).resolve().parents[2]
LI2023_TOL = {  # metric: (relative, absolute) timing allowance around the sims' mean; the wider one counts
    "lateral_force_max_n": (0.15, 0.0),  # a single filtered maximum at the entry
    "lateral_force_stable_n": (0.08, 0.0),
    "thrust_max_n": (0.05, 0.0),
    "drill_time_s": (0.0, 0.2),
    "tracker_deviation_mean_mm": (0.0, 0.06),  # the tracker's noise is 0.05 mm
    "truth_deviation_mean_mm": (0.08, 0.0),
    "truth_deviation_max_mm": (0.08, 0.0),
    "truth_hole_offset_mm": (0.08, 0.0),
}
SIM_NOISE_DRAWS = 20
"""Sim runs on the emulated specimen, one per noise seed (0 .. n-1; seed 0 is the plain run): ~1 s each. Twenty
rather than ten: at the level below, Student's t for one more draw is 6.0 sample SDs with 20 draws, 9.0 with 10."""
FALSE_FAILURE_RATE = 1e-4
"""The chance, for a pipeline that behaves like the sim, that this suite's one distribution test fails: the issue's
bound for the whole suite (this is the suite's only prediction-interval test). Split evenly over the metrics
(Bonferroni, which holds whatever their correlation): each metric's two-sided level is 1 - 1e-4 / 8."""
RESIDUAL_TOL = {  # only what the pipeline's timing does not move (docs/deployment.md §7)
    "thrust_max_n": (0.2, 0.0),
    "tracker_deviation_mean_mm": (0.15, 0.06),
}
"""A learned policy that also sets the feed amplifies the real pipeline's timing: the step-level one's bursts of slow
feed at the entry moved, through the emulator, its drilling time by up to 1.23 s and its peak lateral force by up
to +0.39 N (+50 %), where the sim moves them by at most 0.02 s and 0.014 N for any constant command latency from
2 to 30 ms. The sim is no reference for those; the test checks
instead that the policy is at work through the real backend as in sim (it compensates, it slows the feed)."""
POLICIES = sorted(glob.glob(str(ROOT / "training" / "policies" / "*.zip")))


def _sim_metrics(spec, seed, specimen_seed=None):
    """The sim's cell metrics (the real cell's way) and its truth (``truth_`` keys) for one seeded episode."""
    env = gym.make("drillgym/UR5BoneDrill-v1")
    try:
        options = None if specimen_seed is None else {"specimen_seed": specimen_seed}
        _, info, _ = run_steps(env, make_controller(spec), seed, options=options)
        u = env.unwrapped
        cell = cell_metrics(u.recorder, u.scenario.entry_depth_m, u.scenario.depth_m)
        return {**cell, **{f"truth_{k}": v for k, v in info["metrics"].items()}}
    finally:
        env.close()


def _within_sim_spread(real, spec, specimen_seed, tolerances):
    """Each metric of one emulated run against the sims on its specimen under SIM_NOISE_DRAWS noise draws."""
    sims = [_sim_metrics(spec, seed, specimen_seed) for seed in range(SIM_NOISE_DRAWS)]
    n = len(sims)
    alpha = FALSE_FAILURE_RATE / len(tolerances)
    t = stats.t.ppf(1 - alpha / 2, n - 1)
    for name, (rel, abs_) in tolerances.items():
        values = np.array([sim[name] for sim in sims])
        mean, sd = float(values.mean()), float(values.std(ddof=1))
        half = max(t * sd * math.sqrt(1 + 1 / n), rel * abs(mean), abs_)
        assert abs(real[name] - mean) <= half, (name, real[name], f"sims {mean:.4f} ± {half:.4f}", values.round(4))


def _real_run(start_emulator, tmp_path, spec, seed=0):
    """One episode of ``spec`` (a controller spec, or a controller) through the emulator; its cell metrics and truth."""
    emu = start_emulator(seed=seed)
    env = make_real_env(emu, safety_limits=CI_LIMITS)
    controller = make_controller(spec) if isinstance(spec, str) else spec
    log = tmp_path / "real.parquet"
    logger = EpisodeLogger(env, log, build_header(env, controller.describe(), seed, source="real"))
    try:
        steps, info, ended = run_steps(logger, controller, seed)
        rec = env.unwrapped.recorder
        n_rows = len(rec.t_s)
    finally:
        logger.close()
    truth = emu.control({"cmd": "truth"})
    assert ended and info["failure"] is None, info
    assert info["missed_cycles"] <= 0.05 * info["servo_cycles"], info
    real = {**info["metrics"], **{f"truth_{k}": v for k, v in truth.items() if k != "ok"}}
    assert math.isnan(info["metrics"]["deviation_mean_mm"]) and math.isnan(info["metrics"]["hole_offset_mm"])
    header, df = read_episode_log(log)
    assert header["source"] == "real" and header["env_id"] == "drillgym/UR5BoneDrillReal-v1"
    assert header["plan"]["depth_m"] == pytest.approx(6e-3) and header["seed"] == seed
    assert list(df.columns) == schema_for("real").names and not df.attrs["partial"]
    assert len(df) == n_rows and abs(len(df) - 5 * steps) <= 5
    assert np.all(np.diff(df.t_s) > 0) and df.phase.iloc[-1] == 3 and df.tracker_valid.all()
    return real


def test_li2023_drills_through_the_real_backend_like_in_sim(start_emulator, tmp_path):
    real = _real_run(start_emulator, tmp_path, "li2023")
    _within_sim_spread(real, "li2023", 0, LI2023_TOL)


@pytest.mark.parametrize(
    "policy", POLICIES or [str(ROOT / "training/policies/residual_li2023_sac.zip")], ids=lambda p: Path(p).name
)
def test_residual_policy_drills_through_the_real_backend_like_in_sim(start_emulator, tmp_path, policy):
    if not Path(policy).is_file():
        pytest.skip(f"no trained residual policy yet ({policy})")
    real = _real_run(start_emulator, tmp_path, f"residual:{policy}")
    sim = _sim_metrics(f"residual:{policy}", 0)
    for name, (rel, abs_) in RESIDUAL_TOL.items():
        assert abs(real[name] - sim[name]) <= max(rel * abs(sim[name]), abs_), (name, real[name], sim[name])
    none = _sim_metrics("none", 0)
    base = _sim_metrics("li2023", 0)
    # it compensates: at most half the uncompensated deviation (0.70 mm in sim; 0.11-0.12 mm through the emulator)
    assert real["truth_deviation_mean_mm"] <= 0.5 * none["truth_deviation_mean_mm"], (real, none)
    slowing_s = sim["drill_time_s"] - base["drill_time_s"]
    if slowing_s > 0.5:  # a policy that slows li2023's feed in sim slows it through the real backend too
        assert real["drill_time_s"] >= base["drill_time_s"] + 0.5 * slowing_s, (real["drill_time_s"], sim)


def test_contact_registration_finds_the_tool_where_the_plan_says_through_the_real_backend(start_emulator, tmp_path):
    """The emulated cell's tool is the planned one: the thrust of the real F/T stream must say so (no offset, no
    hold, no waiting in the air), and the registered controller then drills as ``li2023_tuned`` does in sim."""
    controller = make_controller("li2023_registered")
    real = _real_run(start_emulator, tmp_path, controller)
    assert controller.contact and controller.offset_m == 0.0 and controller.hold_m == 0.0 and not controller.in_air
    sim = _sim_metrics("li2023_tuned", 0)
    for name, (rel, abs_) in RESIDUAL_TOL.items():
        assert abs(real[name] - sim[name]) <= max(rel * abs(sim[name]), abs_), (name, real[name], sim[name])
    assert real["truth_deviation_mean_mm"] <= 0.5 * _sim_metrics("none", 0)["truth_deviation_mean_mm"], real


def test_dry_run_streams_nothing_and_logs_what_it_would_send(start_emulator, tmp_path):
    emu = start_emulator()
    commands = tmp_path / "commands.jsonl"
    env = make_real_env(emu, dry_run=True, command_log_path=str(commands))
    try:
        _, info, _ = run_steps(env, make_controller("li2023"), max_steps=20)
        assert info["failure"] is None and info["servo_cycles"] > 100
    finally:
        env.close()
    st = emu.status()
    assert st["scripts_loaded"] == 0 and st["command_counts"] == {} and st["rtde_packages_in"] == 0
    np.testing.assert_allclose(st["rigid_tip_task_m"], [0.0, 0.0, -0.01], atol=1e-9)  # never moved
    lines = commands.read_text().splitlines()
    assert sum('"servoL"' in line for line in lines) > 100 and all('"sent": false' in line for line in lines)
    assert any('"moveL"' in line for line in lines) and any('"setTcp"' in line for line in lines)


def test_reset_refuses_to_move_from_too_far_away(start_emulator):
    from drillgym.envs.real.config import SafetyLimits

    emu = start_emulator()
    env = make_real_env(emu, safety_limits=SafetyLimits(reset_max_distance_m=0.005))
    try:
        with pytest.raises(RuntimeError, match="jog it within 5 mm"):
            env.reset(seed=0)
    finally:
        env.close()
    assert "3" not in emu.status()["command_counts"]  # no moveL


def test_connecting_to_nothing_says_where():
    host = free_loopback_host()
    with pytest.raises(LinkError, match=host):
        gym.make("drillgym/UR5BoneDrillReal-v1", robot_host=host)
    with pytest.raises(TypeError, match="robot_host"):
        gym.make("drillgym/UR5BoneDrillReal-v1")
