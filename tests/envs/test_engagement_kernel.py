"""The compiled lip sums (:mod:`drillgym.envs.drilling.engagement_kernel`) against numpy's masks, bit for bit.

The reference is the plain numpy computation the force tables were first built with: boolean masks of the engaged
elements of shape (depths, radii, angles) and numpy's sums over them. The compiled loop must give the same numbers
to the last bit (a table that differs in its last bit changes every seeded episode's numbers).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillgym.envs.drilling import DrillGeometry, EngagementTable, get_bone_preset
from drillgym.envs.drilling.bone import BONE_PRESETS
from drillgym.envs.drilling.engagement_kernel import lip_sums, pairwise_sum
from drillgym.envs.drilling.force_model import N_ANGULAR, N_RADIAL, _depth_grid


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 16, 120, 127, 128, 129, 255, 256, 1000, 2880, 4097])
def test_pairwise_sum_is_numpys_sum_bit_for_bit(n):
    rng = np.random.default_rng(n)
    for _ in range(20):
        a = rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.uniform(-8, 2, n) * (rng.uniform(size=n) > 0.3)
        assert pairwise_sum(a, 0, n) == a.sum()
        if n > 3:  # a row inside a longer buffer
            assert pairwise_sum(a, 2, n - 3) == a[2 : n - 1].sum()


@pytest.mark.parametrize("n", [300, 2880, 4097])
def test_pairwise_sum_skips_known_zeros_without_changing_the_sum(n):
    rng = np.random.default_rng(n)
    for _ in range(50):
        first, end = sorted(rng.integers(0, n + 1, 2))
        a = np.zeros(n)
        a[first:end] = rng.uniform(0.0, 1.0, end - first) * 10.0 ** rng.uniform(-8, 2, end - first)
        assert pairwise_sum(a, 0, n, first, end) == a.sum()


def _numpy_sums(grid, setback, layer_depth, is_lip, db, r):
    """Masks and sums as numpy computes them (the reference)."""
    e = grid[:, None, None] - setback[None]
    engaged = e > 0.0
    lip_col = is_lip[:, None]
    lip_engaged = ((engaged & lip_col) * db[:, None]).reshape(grid.size, -1).sum(axis=1)
    cortical = engaged & (e < layer_depth)
    out = {"lip_engaged": lip_engaged, "lip_phi": [], "lip_len": [], "lip_moment": []}
    out |= {"chisel_len": [], "cut": []}
    for mask in (cortical, engaged & ~cortical):
        lip = (mask & lip_col) * db[:, None]
        lip_phi = lip.sum(axis=1)
        lip_r_phi = (lip * r[:, None]).sum(axis=1)
        out["lip_phi"].append(lip_phi)
        out["lip_len"].append(lip_phi.sum(axis=1))
        out["lip_moment"].append(lip_r_phi.sum(axis=1))
        out["chisel_len"].append(((mask & ~lip_col) * db[:, None]).reshape(grid.size, -1).sum(axis=1))
        out["cut"].append(mask.reshape(grid.size, -1).any(axis=1))
    return out


@pytest.mark.parametrize("seed", range(12))
def test_lip_sums_equal_numpys_masks_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    geom = DrillGeometry(diameter_m=float(rng.uniform(1.5e-3, 4.5e-3)))
    beta = 0.0 if seed == 0 else math.radians(float(rng.uniform(-60.0, 60.0)))  # past 31°: outer radii lead
    layer = float(rng.uniform(0.5e-3, 8e-3)) / math.cos(beta)
    grid = _depth_grid(geom, beta, layer, layer + float(rng.uniform(1e-3, 15e-3)))
    edges = np.linspace(0.0, geom.radius_m, N_RADIAL + 1)
    r = 0.5 * (edges[1:] + edges[:-1])
    db = np.diff(edges) / math.sin(geom.kappa_rad)
    phi = (np.arange(N_ANGULAR) + 0.5) * 2.0 * math.pi / N_ANGULAR
    setback = r[:, None] * (geom.cot_kappa - np.cos(phi)[None, :] * math.tan(beta))
    is_lip = r >= geom.web_radius_m
    got = lip_sums(grid, setback, layer, is_lip, db, r)
    want = _numpy_sums(grid, setback, layer, is_lip, db, r)
    names = ("lip_engaged", "lip_phi", "lip_len", "lip_moment", "chisel_len", "cut")
    for name, value in zip(names, got[:6], strict=True):
        assert np.array_equal(value, np.asarray(want[name])), name
    assert got[5].any(axis=1).all()  # both materials are cut somewhere: the comparison covers both
    lip_phi, same = got[1], got[6]
    repeated = np.zeros_like(same)
    repeated[:, 1:] = (lip_phi[:, 1:] == lip_phi[:, :-1]).all(axis=2)
    assert np.array_equal(same, repeated)  # "same" says exactly which rows repeat the previous depth's
    assert same.any() and not same.all()


def test_a_table_is_the_same_whatever_else_was_built_before():
    """The compiled sums keep no state between calls: a table built after others equals one built first."""
    names = sorted(BONE_PRESETS)
    args = (DrillGeometry(), get_bone_preset(names[0]), math.radians(25.0), 2e-3, 12e-3)
    first = EngagementTable.build(*args)
    EngagementTable.build(DrillGeometry(diameter_m=3e-3), get_bone_preset(names[1]), 0.4, 5e-3, 20e-3)
    again = EngagementTable.build(*args)
    for a, b in ((first.edge, again.edge), (first.per_chip, again.per_chip), (first.depth_m, again.depth_m)):
        assert np.array_equal(a, b)
