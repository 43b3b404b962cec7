"""SB3's ``VecEnv`` adapter of the batched env against SB3's own ``DummyVecEnv`` of single envs.

With the same seeds (``seed(s)``: episode ``i`` gets ``s + i``) both must give the same observations,
rewards, dones, ``TimeLimit.truncated`` flags, terminal observations and episode metrics within
``TOLERANCE``, through ended and autoreset episodes; SB3's ``VecMonitor`` and an algorithm must run on it.
"""

import gymnasium as gym
import numpy as np
import pytest
from bitwise import largest_difference
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import DummyVecEnv, VecMonitor

from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.training.batched_vec_env import BatchedVecEnv

TOLERANCE = 1e-12
"""As ``tests/envs/test_batched.py``: the compiled step's last-bit rounding."""


def test_the_adapter_steps_like_sb3s_dummy_vec_env_of_single_envs():
    num_envs, seed, steps = 3, 5, 130
    kwargs = {"depth_mm": 2.0, "feed_mm_s": 3.0}  # ~50-step episodes: every slot ends twice or more
    batched = BatchedVecEnv(BatchedDrillEnv(num_envs, **kwargs))
    dummy = DummyVecEnv([lambda: UR5BoneDrillEnv(pybullet_world=False, **kwargs) for _ in range(num_envs)])
    rng = np.random.default_rng(0)
    try:
        batched.seed(seed)
        dummy.seed(seed)
        worst, where = largest_difference(batched.reset(), dummy.reset())
        assert worst == 0.0, where
        ended = 0
        for step in range(steps):
            actions = rng.uniform(-0.5, 0.5, (num_envs, 4)).astype(np.float32)
            obs_b, rew_b, done_b, info_b = batched.step(actions)
            obs_d, rew_d, done_d, info_d = dummy.step(actions)
            assert (done_b == done_d).all(), f"step {step}"
            worst, where = largest_difference((obs_b, rew_b.astype(float)), (obs_d, rew_d.astype(float)))
            assert worst <= TOLERANCE, f"step {step}: {where} differs by {worst:.2e}"
            for i in np.flatnonzero(done_d):
                ended += 1
                assert info_b[i]["TimeLimit.truncated"] == info_d[i]["TimeLimit.truncated"]
                worst, where = largest_difference(
                    (info_b[i]["terminal_observation"], info_b[i]["metrics"]),
                    (info_d[i]["terminal_observation"], info_d[i]["metrics"]),
                )
                assert worst <= TOLERANCE, f"step {step}, episode {i}: {where} differs by {worst:.2e}"
        assert ended >= 2 * num_envs
    finally:
        batched.close()
        dummy.close()


def test_sb3_trains_on_the_adapter_under_its_own_vec_monitor():
    env = VecMonitor(BatchedVecEnv(BatchedDrillEnv(4, depth_mm=2.0, feed_mm_s=3.0)))
    model = PPO("MultiInputPolicy", env, n_steps=16, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)  # 64 steps per slot: past one episode (~50)
    assert model.num_timesteps == 256
    assert len(model.ep_info_buffer) > 0  # VecMonitor saw whole episodes end
    env.close()


def test_the_adapter_refuses_a_vector_env_that_resets_on_the_next_step():
    venv = gym.vector.SyncVectorEnv([lambda: gym.make("CartPole-v1")])
    with pytest.raises(ValueError, match="SAME_STEP"):
        BatchedVecEnv(venv)
    venv.close()


def test_the_adapter_refuses_reset_options_it_cannot_pass_on():
    env = BatchedVecEnv(BatchedDrillEnv(2))
    env.set_options({"scenario": {}})
    with pytest.raises(ValueError, match="no reset options"):
        env.reset()
    env.close()
