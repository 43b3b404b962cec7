"""Spindle sag against the fixed point of a linear torque-speed line, solved apart from the simulator."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs
from drillgym.envs.effects import build_effects
from drillgym.envs.effects.spindle import MIN_SPEED_SHARE, sagged_rpm

QUIET = {"ft_noise_n": 0.0, "tracker_noise_mm": 0.0, "bone_variability": 0.0}


def _stable_cut(spec: str | None) -> tuple[float, float, float, gym.Env]:
    """Thrust (N), spindle torque (N·m) and spindle speed (rpm) at the end of the feed (open loop)."""
    env = gym.make(envs.ENV_IDS[0], **QUIET)
    env.reset(seed=1, options={"effects": build_effects(spec) if spec else None})
    u = env.unwrapped
    last = (0.0, 0.0, 0.0)
    while True:
        _, _, te, tr, _ = env.step(np.zeros(4, np.float32))
        s = u.cell.sample
        if s.cutting:
            last = (s.force[2], s.torque_axis, u.cell.spindle_rpm)
        if te or tr:
            return (*last, env)


@pytest.mark.parametrize("sag_per_nm", [100.0, 250.0])
def test_sagging_spindle_settles_where_the_torque_speed_line_meets_the_cut(sag_per_nm):
    # Full engagement: thrust F = F_e + F_c x and torque M = M_e + M_c x, x = ω₀/ω the chip's growth (the edge
    # terms do not depend on the chip). The motor: ω = ω₀ (1 − k |M|), so 1/x = 1 − k (|M_e| + |M_c| x):
    # k|M_c| x² − (1 − k|M_e|) x + 1 = 0, the smaller root (the one reached from x = 1).
    fz_nom, mz_nom, rpm_nom, env = _stable_cut(None)
    table = env.unwrapped.cell.table
    fe, me = table.edge[-1][2], table.edge[-1][3]
    fc, mc = fz_nom - fe, mz_nom - me
    k = sag_per_nm
    b = 1.0 - k * abs(me)
    x = (b - math.sqrt(b * b - 4.0 * k * abs(mc))) / (2.0 * k * abs(mc))
    fz, mz, rpm = _stable_cut(f"spindle_sag:sag_per_nm={k}")[:3]
    assert rpm_nom == env.unwrapped.scenario.spindle_rpm
    assert rpm == pytest.approx(rpm_nom / x, rel=1e-9)
    assert fz == pytest.approx(fe + fc * x, rel=1e-9)
    assert mz == pytest.approx(me + mc * x, rel=1e-9)
    assert x > 1.05  # the sag is large enough to see


def test_spindle_speed_is_floored_near_stall_and_needs_no_torque_to_stay_at_speed():
    assert sagged_rpm(20000.0, 500.0, 0.0) == 20000.0
    assert sagged_rpm(20000.0, 100.0, -2e-3) == pytest.approx(16000.0)
    assert sagged_rpm(20000.0, 500.0, 0.05) == 20000.0 * MIN_SPEED_SHARE
