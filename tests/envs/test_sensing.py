import gymnasium as gym
import numpy as np
import pytest

from drillgym.envs.constants import FT_RESOLUTION, MAX_CORRECTION_M
from drillgym.envs.sensors import ForceTorqueSensor, PositionTracker, latest_sample_time_s


def test_ft_readings_are_quantised_to_the_mini40_resolution():
    rng = np.random.default_rng(0)
    ft = ForceTorqueSensor(0.05, rng)
    r = ft.sample_block(np.tile([1.234, -0.5, 7.777, 0.01, 0.002, -0.003], (200, 1)))
    steps = r / FT_RESOLUTION
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)


def test_ft_noise_has_the_requested_standard_deviation():
    ft = ForceTorqueSensor(0.2, np.random.default_rng(1))
    r = ft.sample_block(np.zeros((20000, 6)))
    assert r[:, :3].std(axis=0) == pytest.approx([0.2, 0.2, 0.2], rel=0.05)
    assert r[:, :3].mean(axis=0) == pytest.approx([0, 0, 0], abs=0.01)


def test_noise_free_ft_reads_the_true_wrench_to_within_half_a_count():
    ft = ForceTorqueSensor(0.0, np.random.default_rng(0))
    w = np.array([[0.123, 4.567, -8.9, 0.0123, -0.0456, 0.001]])
    np.testing.assert_allclose(ft.sample_block(w)[0], w[0], atol=0.5 * FT_RESOLUTION.max())


def test_tracker_noise_has_the_requested_standard_deviation():
    tr = PositionTracker(5e-5, np.random.default_rng(2))
    r = np.array([tr.sample(np.zeros(3)) for _ in range(5000)])
    assert r.std(axis=0) == pytest.approx([5e-5] * 3, rel=0.06)


def test_rtde_stream_time_stamps_are_multiples_of_8_ms():
    assert latest_sample_time_s(0.05, 125.0) == pytest.approx(0.048)
    assert latest_sample_time_s(0.048, 125.0) == pytest.approx(0.048)
    assert latest_sample_time_s(0.0479, 125.0) == pytest.approx(0.040)


def _rigid_tip_after(latency_s: float, steps: int) -> np.ndarray:
    env = gym.make("drillgym/UR5BoneDrill-v1", latency_s=latency_s, servo_time_constant_s=0.001)
    env.reset(seed=0)
    action = np.array([0.5, 0.0, 0.0, 0.0], np.float32)
    for _ in range(steps):
        env.step(action)
    cell = env.unwrapped.cell
    tip_base = cell.R_base_task @ cell.rigid_tip
    env.close()
    return tip_base


def test_a_correction_takes_effect_only_after_the_command_latency():
    # base-x correction of 1 mm; latency 0.12 s: nothing after 2 steps (0.1 s), all of it after 4 (0.2 s)
    early = _rigid_tip_after(0.12, 2)
    late = _rigid_tip_after(0.12, 4)
    assert abs(early[0]) < 1e-9
    assert late[0] == pytest.approx(0.5 * MAX_CORRECTION_M, rel=1e-3)


def test_rtde_tcp_error_observes_the_commanded_correction():
    env = gym.make("drillgym/UR5BoneDrill-v1", latency_s=0.0, servo_time_constant_s=0.001)
    env.reset(seed=0)
    for _ in range(3):
        obs, *_ = env.step(np.array([0.0, -0.5, 0.0, 0.0], np.float32))
    env.close()
    assert obs["tcp_error_base_m"][1] == pytest.approx(-0.5 * MAX_CORRECTION_M, rel=1e-3)
    assert obs["correction_base_m"][1] == pytest.approx(-0.5 * MAX_CORRECTION_M, rel=1e-6)
