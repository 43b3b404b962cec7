"""A bundle's policy is built alone, without its algorithm, and predicts as the saved model does."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from drillgym.envs.errors import UserError
from drillgym.training.model import ALGO_CLASSES
from drillgym.training.policy_bundle import NAMED_POLICIES, POLICY_DIR, load_policy


def _observations(space: gym.Space, n: int) -> list:
    space.seed(7)
    return [space.sample() for _ in range(n)]


def _assert_same_actions(zip_path: Path, algo: str) -> None:
    model = ALGO_CLASSES[algo].load(zip_path, device="cpu")
    policy = load_policy(zip_path)
    assert type(policy) is type(model.policy)
    for obs in _observations(model.observation_space, 50):
        want, _ = model.predict(obs, deterministic=True)
        got, _ = policy.predict(obs, deterministic=True)
        np.testing.assert_array_equal(got, want)
        assert got.dtype == want.dtype


@pytest.mark.parametrize("name", sorted(NAMED_POLICIES))
def test_shipped_policy_predicts_as_its_saved_model(name: str) -> None:
    _assert_same_actions(POLICY_DIR / NAMED_POLICIES[name], "sac")


@pytest.mark.parametrize("algo", ["sac", "td3", "ppo"])
def test_policy_of_each_algorithm_predicts_as_its_saved_model(algo: str, tmp_path: Path) -> None:
    model = ALGO_CLASSES[algo]("MlpPolicy", gym.make("Pendulum-v1"), seed=3, device="cpu")
    for p in model.policy.parameters():  # weights away from their initialisation, so a wrong load shows
        p.data.add_(0.05 * np.pi)
    model.save(tmp_path / "model.zip")
    _assert_same_actions(tmp_path / "model.zip", algo)


def test_policy_is_built_without_optimisers() -> None:
    """Loading the shipped policy imports neither torch's compiler (pulled in by a first optimiser) nor builds one."""
    code = (
        "import sys; from drillgym.training.policy_bundle import load_bundle; b = load_bundle('shipped'); "
        "print(type(b.policy.actor.optimizer).__name__, 'torch._dynamo' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["_NoOptimizer", "False"]


def test_file_without_policy_is_a_clear_error(tmp_path: Path) -> None:
    import zipfile

    bad = tmp_path / "empty.zip"
    with zipfile.ZipFile(bad, "w") as z:
        z.writestr("data", "{}")
    with pytest.raises(UserError, match="holds no SB3 policy"):
        load_policy(bad)
