"""Joint backlash: the links trail the motors by half the play, and the tool sits where the links put it."""

from __future__ import annotations

import gymnasium as gym
import numpy as np

from drillgym import envs
from drillgym.envs.effects.backlash import JointBacklash
from drillgym.envs.robot.ur5 import TCP_FRAME, TRACKER_FRAME

QUIET = {"ft_noise_n": 0.0, "tracker_noise_mm": 0.0, "bone_variability": 0.0}


def test_links_trail_the_motors_by_half_the_play_and_carry_the_tool_and_marker_there():
    play = 4e-4
    backlash = JointBacklash(play_rad=play)
    env = gym.make(envs.ENV_IDS[0], **QUIET)
    env.reset(seed=1, options={"effects": [backlash]})
    cell = env.unwrapped.cell
    q_start = cell.q_motor_rad.copy()
    for _ in range(60):  # the approach and the start of the feed: every joint keeps turning one way
        q_motor = cell.q_motor_rad.copy()  # the links are moved at a step's start, from the motors there
        env.step(np.zeros(4, np.float32))
    moved = q_motor[:3] - q_start[:3]
    turned = np.abs(moved) > play  # a joint that turned past its play drags its link at the play's far end
    assert turned.any()
    lag = backlash.q_link[:3] - q_motor[:3]
    np.testing.assert_allclose(lag[turned], -0.5 * play * np.sign(moved[turned]), rtol=0, atol=1e-12)
    # The tool and the marker where the links put them (the kinematic model, not the compiled chains).
    q_link = q_motor.copy()
    q_link[:3] = backlash.q_link[:3]
    kin = cell.kin
    tip = cell.R_base_task.T @ (kin.fk(q_link, TCP_FRAME)[:3, 3] - kin.fk(q_motor, TCP_FRAME)[:3, 3])
    marker = kin.fk(q_link, TRACKER_FRAME)[:3, 3] - kin.fk(q_motor, TRACKER_FRAME)[:3, 3]
    np.testing.assert_allclose(cell.geometry_offset_task_m, tip, rtol=0, atol=1e-9)
    np.testing.assert_allclose(cell.marker_offset_base_m, marker, rtol=0, atol=1e-9)
    assert np.linalg.norm(tip) > 20e-6  # the play's lever: tens of µm
    env.close()
