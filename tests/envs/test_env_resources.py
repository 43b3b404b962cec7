from __future__ import annotations

import resource
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as pb
import pytest

from drillgym import envs
from drillgym.envs.drill_env import UR5BoneDrillEnv

ENV_ID = envs.ENV_IDS[0]
MAX_CLIENT_ID = 1024  # PyBullet's client-slot limit is far below this


def rss_mb() -> float:
    status = Path("/proc/self/status")
    if status.exists():
        for line in status.read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    # Fallback: peak RSS (kB on Linux, bytes on macOS) - growth of the peak still bounds a leak.
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0 if sys.platform == "darwin" else 1024.0)


def connected_clients() -> set[int]:
    return {i for i in range(MAX_CLIENT_ID) if pb.isConnected(physicsClientId=i)}


def test_rgb_array_render_is_uint8_image_with_content():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    try:
        env.reset(seed=0)
        for _ in range(60):  # into the bone
            env.step(np.zeros(4, np.float32))
        frame = env.render()
        assert isinstance(frame, np.ndarray)
        assert frame.dtype == np.uint8
        assert frame.ndim == 3 and frame.shape[2] == 3 and frame.shape[0] > 0 and frame.shape[1] > 0
        colours = np.unique(frame.reshape(-1, 3), axis=0)
        assert len(colours) > 10, f"only {len(colours)} distinct colours"
        assert frame.std() > 5.0
    finally:
        env.close()


def test_render_without_render_mode_returns_none():
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0)
        assert env.render() is None
    finally:
        env.close()


@pytest.mark.parametrize("mode", ["human", "rgb", "ansi"])
def test_unsupported_render_mode_raises_value_error(mode):
    # Direct construction: gym.make(render_mode="human") is rewritten by gymnasium itself into
    # rgb_array + HumanRendering wrapper for envs that offer rgb_array, so it never reaches the env.
    with pytest.raises(ValueError, match=mode):
        UR5BoneDrillEnv(render_mode=mode)


@pytest.mark.parametrize("mode", ["rgb", "ansi"])
def test_unsupported_render_mode_through_gym_make_raises_value_error(mode):
    with pytest.warns(UserWarning, match="render_mode"), pytest.raises(ValueError, match=mode):
        gym.make(ENV_ID, render_mode=mode)


def test_close_disconnects_the_pybullet_client_and_is_idempotent():
    env = gym.make(ENV_ID, render_mode="rgb_array")
    env.reset(seed=0)
    env.render()
    client = env.unwrapped.world.client
    assert pb.isConnected(physicsClientId=client)
    env.close()
    assert not pb.isConnected(physicsClientId=client)
    env.close()
    env.unwrapped.close()
    assert not pb.isConnected(physicsClientId=client)


def test_thousand_resets_do_not_leak_memory_or_bodies():
    env = gym.make(ENV_ID)
    try:
        client = env.unwrapped.world.client
        zero = np.zeros(4, np.float32)

        def reset_and_step(seed: int) -> None:
            env.reset(seed=seed)
            for _ in range(3):
                env.step(zero)

        for seed in range(100):
            reset_and_step(seed)
        bodies = pb.getNumBodies(physicsClientId=client)
        rss_100 = rss_mb()
        for seed in range(100, 1000):
            reset_and_step(seed)
        growth = rss_mb() - rss_100
        assert growth < 20.0, f"RSS grew by {growth:.1f} MB between 100 and 1000 resets"
        assert pb.getNumBodies(physicsClientId=client) == bodies
    finally:
        env.close()


def test_creating_and_closing_twenty_envs_does_not_grow_connected_clients():
    before = connected_clients()
    ids = []
    for _ in range(20):
        env = gym.make(ENV_ID)
        client = env.unwrapped.world.client
        ids.append(client)
        assert pb.isConnected(physicsClientId=client)
        env.close()
        assert not pb.isConnected(physicsClientId=client)
    assert connected_clients() == before
    assert not any(pb.isConnected(physicsClientId=i) for i in ids)


@pytest.mark.parametrize("beta_deg", [10.0, 40.0])
def test_the_bone_stands_on_a_stand_on_the_floor_and_the_arm_is_in_frame(beta_deg):
    import pybullet as pb

    env = gym.make(ENV_ID, render_mode="rgb_array", beta_deg=beta_deg)
    try:
        env.reset(seed=0)
        world = env.unwrapped.world
        bone_low = pb.getAABB(world.bone, physicsClientId=world.client)[0]  # the bone has a collision shape
        stand_z = pb.getBasePositionAndOrientation(world.stand, physicsClientId=world.client)[0][2]
        floor_z = pb.getBasePositionAndOrientation(world.floor, physicsClientId=world.client)[0][2]
        half = world.STAND_HALF_HEIGHT_M
        # the stand's top meets the bone's lowest corner and its foot reaches below the floor (world z up)
        assert stand_z + half == pytest.approx(bone_low[2], abs=1e-3)
        assert stand_z - half < floor_z
        frame = env.render()
        top_row = frame[0].reshape(-1, 3)
        assert len(np.unique(top_row, axis=0)) == 1, "the arm reaches the image's top edge"
    finally:
        env.close()
