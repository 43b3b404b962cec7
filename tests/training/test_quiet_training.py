"""Training prints no warning that says nothing: the eval env's vectoriser, an empty curve."""

import warnings

import gymnasium as gym
import pytest
from stable_baselines3 import SAC
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

from drillgym.training.callbacks import BaseComparisonEvalCallback
from drillgym.training.plots import plot_curves

SAME_TYPE = "Training and eval env are not of the same type"


def _pendulum() -> gym.Env:
    return gym.make("Pendulum-v1", max_episode_steps=20)


def _init_warnings(train_env, eval_env) -> list[str]:
    model = SAC("MlpPolicy", train_env, learning_starts=0, device="cpu")
    callback = BaseComparisonEvalCallback(eval_env, 1, n_eval_episodes=1, eval_freq=10)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        callback.init_callback(model)
    return [str(w.message) for w in caught]


@pytest.fixture
def workers():
    venv = SubprocVecEnv([_pendulum, _pendulum], start_method="fork")
    yield venv
    venv.close()


def test_subprocess_workers_with_an_in_process_eval_env_wrapped_alike_raise_no_type_warning(workers):
    # normalize_obs: false with n_envs > 1 (the schedule residual): SubprocVecEnv against DummyVecEnv
    caught = _init_warnings(workers, DummyVecEnv([_pendulum]))
    assert not [m for m in caught if SAME_TYPE in m]


def test_an_eval_env_wrapped_otherwise_is_still_warned_about(workers):
    caught = _init_warnings(VecNormalize(workers), DummyVecEnv([_pendulum]))
    assert [m for m in caught if SAME_TYPE in m]


def test_the_curves_of_a_run_without_evaluations_draw_without_a_warning(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plot_curves([], tmp_path / "training_curves.png")
    assert (tmp_path / "training_curves.png").stat().st_size > 0
