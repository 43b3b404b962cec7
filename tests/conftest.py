"""Shared fixtures and helpers for the drillgym test suite."""

from __future__ import annotations

import logging
import os

# One thread per BLAS / torch pool in each test process: pytest-xdist already runs one process per core, and
# a second thread would steal the core that a real-time test (the emulated UR pipeline) runs on.
os.environ.setdefault("OMP_NUM_THREADS", "1")

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401  (registers the ids)
from drillgym.eval.bench.rollout import EpisodeResult, run_episode

ENV_ID = "drillgym/UR5BoneDrill-v1"


@pytest.fixture(scope="session", autouse=True)
def sb3_logdir(tmp_path_factory):
    """SB3 makes a log folder for every ``learn`` without TensorBoard (in the system temp folder by default):
    keep the tests' folders inside pytest's own temporary tree."""
    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3"))
    yield
    if previous is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = previous


@pytest.fixture(scope="module")
def ray_local():
    """One local Ray instance with 2 CPUs per test module (starting Ray takes seconds); skips without Ray."""
    ray = pytest.importorskip("ray")
    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level=logging.WARNING)
    yield ray
    ray.shutdown()


def run_zero_action(seed: int = 0, **scenario) -> EpisodeResult:
    """One uncompensated episode of a scenario; the env is closed afterwards."""
    env = gym.make(ENV_ID, **scenario)
    try:
        return run_episode(env, None, seed)
    finally:
        env.close()


def r_squared(x: np.ndarray, y: np.ndarray) -> float:
    """Coefficient of determination of a least-squares straight line through (x, y)."""
    coef = np.polyfit(x, y, 1)
    resid = y - np.polyval(coef, x)
    return 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())
