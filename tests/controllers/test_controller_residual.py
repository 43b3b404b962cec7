"""The residual controller (controllers/residual.py): one composition for training and deployment."""

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs  # noqa: F401
from drillgym.controllers import make_controller
from drillgym.controllers.residual import BASE_ACTION_KEY, PLAN_KEY, ResidualController, ResidualSpec, combine

ENV_ID = "drillgym/UR5BoneDrill-v1"


def test_a_policy_function_acts_on_top_of_its_base_as_combine_says():
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=1)
    plan = env.unwrapped.plan
    seen = []

    def policy(policy_obs):
        seen.append(policy_obs)
        return np.array([0.5, -0.25, -1.0], dtype=np.float32)

    spec = ResidualSpec(scale=0.5, mode="add", residual_feed=True, observe_plan=True)
    ctl = ResidualController(make_controller("li2023"), spec, policy)
    base = make_controller("li2023")
    ctl.set_plan(plan)
    base.set_plan(plan)
    for start in (True, False, False):
        action, _ = ctl.predict(obs, episode_start=np.array([start]))
        base_action, _ = base.predict(obs, episode_start=np.array([start]))
        np.testing.assert_array_equal(seen[-1][BASE_ACTION_KEY], base_action)
        np.testing.assert_array_equal(
            action, combine(base_action, np.array([0.5, -0.25, -1.0]), 0.5, plan.R_base_task, "add", "base")
        )
        obs, *_ = env.step(action)
    assert PLAN_KEY in seen[0] and seen[0][PLAN_KEY][0] == pytest.approx(plan.beta_rad)
    env.close()


def test_a_residual_without_a_policy_cannot_act_alone_and_bad_residuals_are_refused():
    env = gym.make(ENV_ID)
    obs, _ = env.reset(seed=0)
    ctl = ResidualController(make_controller("none"), ResidualSpec())
    ctl.set_plan(env.unwrapped.plan)
    with pytest.raises(RuntimeError, match="no policy"):
        ctl.act(obs)
    ctl.observe(obs)
    with pytest.raises(ValueError, match="shape"):
        ctl.compose(np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        ctl.compose(np.array([np.nan, 0.0]))
    env.close()


@pytest.mark.parametrize(
    "kwargs", [{"scale": 0.0}, {"scale": 3.0}, {"mode": "mul"}, {"axes": "z"}, {"feed_ceiling": "sky"}]
)
def test_an_invalid_residual_spec_is_a_clear_error(kwargs):
    with pytest.raises(ValueError):
        ResidualSpec(**kwargs)
