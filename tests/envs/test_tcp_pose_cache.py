"""The compiled step's TCP pose kept from the last Jacobian (``tcp_pose_base``): used, and the same bits as fresh."""

import copy

import numpy as np

from drillgym.envs.batched import BatchedDrillEnv


def _stepped(env: BatchedDrillEnv, steps: int, change=None) -> np.ndarray:
    env = copy.deepcopy(env)
    actions = np.random.default_rng(1).uniform(-0.3, 0.3, (steps, env.num_envs, 4)).astype(np.float32)
    for k in range(steps):
        if change is not None:
            change(env.state)
        env.step(actions[k])
    return env.record.copy()


def test_the_kept_pose_gives_the_numbers_of_a_pose_computed_afresh_and_is_the_one_used():
    env = BatchedDrillEnv(3)
    env.reset(seed=4)
    env.step(np.zeros((3, 4), dtype=np.float32))
    assert np.array_equal(env.state["tcp_pose_q_rad"], env.state["q_motor_rad"])  # kept for the next step's IK
    kept = _stepped(env, 40)

    def forget(state):
        state["tcp_pose_q_rad"] = np.nan  # every step computes the pose afresh

    def corrupt(state):
        state["tcp_pose_base"][:, 9] += 1e-4  # a wrong pose, still marked as the current angles'

    assert np.array_equal(kept, _stepped(env, 40, forget))
    assert not np.array_equal(kept, _stepped(env, 40, corrupt))


def test_angles_changed_from_outside_are_not_read_with_the_old_pose():
    env = BatchedDrillEnv(2)
    env.reset(seed=9)
    env.step(np.zeros((2, 4), dtype=np.float32))

    def nudge(state):
        state["q_motor_rad"][:, 0] += 1e-6

    def nudge_and_forget(state):
        nudge(state)
        state["tcp_pose_q_rad"] = np.nan

    assert np.array_equal(_stepped(env, 10, nudge), _stepped(env, 10, nudge_and_forget))
