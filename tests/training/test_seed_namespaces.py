"""No tuning, training or selection episode drills a judge episode's specimen, whatever seeds a user passes.

Every ``reset`` of the simulated env is spied on (its seed and the specimen hardness it drew). The judge's
episodes are the benchmark grid's (every suite, seeds 0..19); the others are what the tuners, the training
wrappers (given any reset seed, as SB3 gives ``run seed + rank``) and the selection actually reset with.
"""

import gymnasium as gym
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from drillgym.envs import SIM_ENV_ID
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.seeds import Purpose, purpose_of
from drillgym.eval.bench.episode import grid_jobs
from drillgym.eval.bench.suites import SUITES
from drillgym.eval.bench.tune_table import anchor_jobs
from drillgym.training.config import TrainConfig
from drillgym.training.domain_randomization import DomainRandomization
from drillgym.training.env_factory import _schedule_eval_episodes, schedule_env
from drillgym.training.selection import validation_episodes

JUDGE_SEEDS = 20
SCHEDULE = {"residual_mode": "schedule", "normalize_obs": False, "base": "li2023_tuned"}

user_seeds = st.integers(min_value=0, max_value=2**62)


@pytest.fixture(scope="module")
def spy():
    """Record (seed, specimen hardness) of every reset of the simulated env in this process."""
    calls: list[tuple[int | None, float]] = []
    original = UR5BoneDrillEnv.reset

    def reset(self, *, seed=None, options=None):
        out = original(self, seed=seed, options=options)
        calls.append((seed, float(self.specimen_hardness)))
        return out

    UR5BoneDrillEnv.reset = reset
    yield calls
    UR5BoneDrillEnv.reset = original


@pytest.fixture(scope="module")
def judge(spy):
    """The judge's episode seeds and the specimens they draw (the same for every scenario)."""
    seeds = {job.seed for job in grid_jobs(list(SUITES), ["none"], JUDGE_SEEDS)}
    env = gym.make(SIM_ENV_ID)
    spy.clear()
    for s in sorted(seeds):
        env.reset(seed=s)
    hardness = {h for _, h in spy}
    env.close()
    assert len(hardness) == len(seeds) == JUDGE_SEEDS
    return seeds, hardness


def assert_apart(calls, judge, purpose):
    seeds, hardness = judge
    given_seeds = [s for s, _ in calls if s is not None]
    assert given_seeds, "the job reset the env without any seed of its own"
    assert all(purpose_of(s) == purpose for s in given_seeds), sorted({purpose_of(s) for s in given_seeds})
    assert not seeds & set(given_seeds)
    assert not hardness & {h for _, h in calls}


def test_tuners_reset_only_with_tuning_seeds(judge):
    entry = {job.seed for job in grid_jobs(["paper", "sweep"], ["li2023"], 50, Purpose.TUNE)}
    table = {s for job in anchor_jobs(seeds=50, seed_offset=10**6) for s in job.seeds}
    for seeds in (entry, table):
        assert {purpose_of(s) for s in seeds} == {Purpose.TUNE}
        assert not seeds & judge[0]


@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(run_seed=st.integers(min_value=0, max_value=10**6), reset_seed=st.one_of(st.none(), user_seeds))
def test_a_schedule_training_env_never_drills_a_judge_specimen(spy, judge, run_seed, reset_seed):
    env = schedule_env(TrainConfig(**SCHEDULE, seed=run_seed), rank=run_seed % 3)
    spy.clear()
    env.reset(seed=reset_seed)
    env.reset()
    env.close()
    assert_apart(list(spy), judge, Purpose.TRAIN)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(reset_seed=st.one_of(st.none(), st.integers(min_value=0, max_value=JUDGE_SEEDS), user_seeds))
def test_a_randomised_step_level_env_never_drills_a_judge_specimen(spy, judge, reset_seed):
    env = DomainRandomization(gym.make(SIM_ENV_ID), stream_keys=(0, 1))
    spy.clear()
    env.reset(seed=reset_seed)
    env.reset()  # continues the stream the first reset seeded
    env.reset()
    env.close()
    assert_apart(list(spy), judge, Purpose.TRAIN)


def test_selection_and_evaluation_holes_use_selection_seeds(judge):
    for cfg in (
        TrainConfig(**SCHEDULE, eval_episodes=4, selection_paper_episodes=3),
        TrainConfig(**SCHEDULE, eval_episodes=3, eval_scenarios="paper"),
    ):
        holes = validation_episodes(cfg) + _schedule_eval_episodes(cfg, None)
        seeds = {s for _, s in holes}
        assert {purpose_of(s) for s in seeds} == {Purpose.SELECT}
        assert not seeds & judge[0]
