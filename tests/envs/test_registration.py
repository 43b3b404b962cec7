"""Registration error: where the drill first touches the real surface, against the drill's point geometry."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from drillgym import envs
from drillgym.envs.effects import build_effects

QUIET = {"ft_noise_n": 0.0, "tracker_noise_mm": 0.0, "bone_variability": 0.0}


def _first_touch(spec: str | None) -> tuple[tuple[float, float], float, gym.Env]:
    """Open loop: the tip's depth along the planned axis (task z, m; the true tip, bone frame) at the two samples
    before the first one recorded in contact, and the commanded depth (m) at that one."""
    env = gym.make(envs.ENV_IDS[0], **QUIET)
    env.reset(seed=1, options={"effects": build_effects(spec) if spec else None})
    u = env.unwrapped
    while not any(env.step(np.zeros(4, np.float32))[2:4]):
        pass
    k = int(np.flatnonzero(np.asarray(u.recorder.stage) > 0)[0])
    z = np.asarray(u.recorder.tip_task_m)[:, 2]
    return (float(z[k - 2]), float(z[k - 1])), float(u.recorder.depth_cmd_m[k]), env


@pytest.mark.parametrize(("dz_m", "dbeta_rad"), [(0.0, 0.0), (5e-4, 0.0), (0.0, 0.1), (3e-4, -0.12)])
def test_drill_first_touches_the_real_surface_where_its_point_meets_it(dz_m, dbeta_rad):
    # The uphill lip corner of a point of half-angle κ meets a surface inclined by β at r (cot κ − tan β) behind
    # the tip (0 if that is ahead of it: the tip itself touches first): the tip is there as contact starts (to a
    # sample or two: the stages differ by ~90 µm between these tilts, a sample is 5 µm). The real surface is dz further along the axis: the command reaches it dz later than planned
    # (dz >= 0 here: both touches then happen at the feed's speed, so the servo's lag behind the command is the same).
    (before, at), cmd, env = _first_touch(f"registration:surface_dz_m={dz_m},slope_error_rad={dbeta_rad}")
    sc = env.unwrapped.scenario
    geo = sc.geometry
    touch = min(0.0, geo.radius_m * (geo.cot_kappa - math.tan(abs(sc.beta_rad + dbeta_rad))))
    step_m = at - before
    assert at == pytest.approx(touch, abs=2.0 * step_m)  # the onset of contact resolves to a sample or two
    _, cmd_planned, _ = _first_touch(f"registration:slope_error_rad={dbeta_rad}")
    assert cmd - cmd_planned == pytest.approx(dz_m, abs=step_m)


def test_a_tilted_surface_cuts_like_a_plan_made_for_that_tilt():
    env = gym.make(envs.ENV_IDS[0], **QUIET)
    env.reset(seed=1, options={"effects": build_effects("registration:slope_error_rad=0.1")})
    cell = env.unwrapped.cell
    planned = gym.make(envs.ENV_IDS[0], beta_deg=30.0 + math.degrees(0.1), **QUIET).unwrapped.cell
    for name in ("depth_m", "edge", "per_chip", "engaged_fraction"):
        np.testing.assert_array_equal(getattr(cell.solver.table, name), getattr(planned.solver.table, name))
    assert cell.solver.tan_beta == planned.solver.tan_beta and cell.solver._bounds == planned.solver._bounds
    env.reset(seed=1, options={"effects": None})  # and switched off, the plan's surface again
    nominal = gym.make(envs.ENV_IDS[0], **QUIET).unwrapped.cell
    assert cell.solver.beta_rad == nominal.solver.beta_rad and cell.solver._bounds == nominal.solver._bounds
    np.testing.assert_array_equal(cell.table.edge, nominal.table.edge)
