"""Stacked offline models (``controllers/stacked_models.py``) read as ``np.interp`` reads each, bit for bit."""

import math

import numpy as np

from drillgym.controllers.models import OfflineForceModel
from drillgym.controllers.stacked_models import StackedOfflineModels
from drillgym.envs.drill_env import UR5BoneDrillEnv


def _models() -> list[OfflineForceModel]:
    out = []
    for changes in ({}, {"beta_deg": -25.0, "depth_mm": 12.0}, {"feed_mm_s": 1.4, "drill_diameter_mm": 2.5}):
        env = UR5BoneDrillEnv(pybullet_world=False, **changes)
        out.append(OfflineForceModel.for_plan(env.plan))
        env.close()
    return out


def test_each_episode_reads_its_own_model_as_np_interp_bit_for_bit():
    models = _models()
    rng = np.random.default_rng(0)
    order = [0, 2, 1, 1, 0, 2, 2]
    stacked = StackedOfflineModels([models[k] for k in order])
    for _ in range(200):
        depth = rng.uniform(-2e-3, 16e-3, len(order))
        grid_points = rng.integers(0, 3, len(order)) == 0  # some depths exactly on a grid point or an end
        for i in np.flatnonzero(grid_points):
            xp = models[order[i]].depth_m
            depth[i] = xp[rng.integers(0, xp.size)] if rng.uniform() < 0.8 else xp[-1]
        got = np.zeros((len(order), 3))
        stacked.lateral_into(depth, got)
        for i, k in enumerate(order):
            want = np.zeros((1, 3))
            models[k].lateral_into(depth[i : i + 1], want)
            assert np.array_equal(got[i], want[0]), (i, depth[i])


def test_a_nan_depth_reads_nan_and_outside_the_table_reads_zero():
    models = _models()
    stacked = StackedOfflineModels(models)
    out = np.zeros((3, 2))
    stacked.lateral_into(np.array([math.nan, -1.0, 1.0]), out)
    assert np.isnan(out[0]).all() and (out[1:] == 0.0).all()
