"""Controllers of different holes stepped as one batch (``Controller.stack``): each episode as if alone, bit for bit.

A schedule residual's training drills many holes at once, each with its own plan and tuning; the li2023 family
stacks them into one controller whose arithmetic stays elementwise per episode. Every episode's metrics and rewards
must be those of the same controller driving the single env.
"""

import gymnasium as gym
import numpy as np
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.base import stack_controllers
from drillgym.controllers.li2023 import Li2023Controller
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec
from drillgym.controllers.rollout import run_batch, run_episode
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.errors import UserError

HOLES = [  # (controller, scenario changes, seed)
    ("li2023_tuned", {"beta_deg": 10.0, "feed_mm_s": 1.2}, 3),
    ("li2023_tuned:kp=2.5,y_gain=1.6,entry_feed_scale=0.3,entry_depth_mm=2", {"bone": "porcine_femur"}, 3),
    ("li2023", {"stickout_mm": 45.0, "beta_deg": -20.0}, 8),
    ("li2023:y_gain=0.8,axes=x", {"cortical_thickness_mm": 3.0}, 1),
    ("schedule", {"feed_mm_s": 0.7, "beta_deg": 35.0}, 5),
    ("zhang2005", {"beta_deg": 20.0}, 2),  # does not stack: steps alone beside the others
]


def _controller(spec: str):
    if spec == "schedule":
        return PlanScheduledController(ScheduleSpec(), policy=lambda _obs: np.array([0.4, -0.7, 0.2, 0.9]))
    return make_controller(spec)


def test_stacked_controllers_drill_each_hole_as_alone_bit_for_bit():
    alone = []
    for spec, changes, seed in HOLES:  # a fresh env each: a scenario change stays for the env's next episodes
        env = gym.make(SIM_ENV_ID)
        alone.append(run_episode(env, _controller(spec), seed, keep_trace=False, options={"scenario": changes}))
        env.close()
    batch = BatchedDrillEnv(len(HOLES), autoreset=False)
    try:
        together = run_batch(
            batch, [_controller(s) for s, _, _ in HOLES], [h[2] for h in HOLES], scenarios=[h[1] for h in HOLES]
        )
    finally:
        batch.close()
    for a, b, hole in zip(alone, together, HOLES, strict=True):
        assert a.row() == b.row(), hole
        assert np.array_equal(a.rewards, b.rewards), hole


def test_controllers_group_by_what_can_step_together():
    from drillgym.envs.drill_env import UR5BoneDrillEnv

    env = UR5BoneDrillEnv(pybullet_world=False)
    env.reset(seed=0)
    controllers = [_controller(spec) for spec, _, _ in HOLES]
    for c in controllers:
        c.set_plan(env.unwrapped.plan)
    groups = {tuple(idx): type(c).__name__ for idx, c in stack_controllers(controllers)}
    # the slow entries (li2023_tuned and the schedule's tuned base) step together; so do the plain li2023s
    assert groups == {(0, 1, 4): "SlowEntry", (2, 3): "Li2023Controller", (5,): "Zhang2005Controller"}
    env.close()


def test_controllers_of_other_timing_do_not_stack():
    from drillgym.envs.drill_env import UR5BoneDrillEnv

    env = UR5BoneDrillEnv(pybullet_world=False)
    env.reset(seed=0)
    a, b = make_controller("li2023"), make_controller("li2023:point_period_s=0.3")
    for c in (a, b):
        c.set_plan(env.unwrapped.plan)
    assert a.stack_key() != b.stack_key()
    assert len(stack_controllers([a, b])) == 2
    with pytest.raises(UserError, match="same timing"):
        Li2023Controller.stack([a, b])
    env.close()
