"""The compiled one-point interpolation (envs/interp_kernel.py) against np.interp, bit for bit."""

import numpy as np
import pytest

from drillgym.envs.interp_kernel import interp_one


@pytest.mark.parametrize("seed", range(5))
def test_interp_one_equals_np_interp_bit_for_bit_inside_on_the_grid_and_outside(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 400))
    xp = np.unique(rng.normal(size=n))
    n = xp.size
    fp = rng.normal(size=n)
    fp[rng.integers(0, n, 5)] = 0.0  # flat stretches, exact zeros
    xs = np.concatenate([rng.uniform(xp[0] - 1, xp[-1] + 1, 500), xp, [xp[0], xp[-1], np.nan, -np.inf, np.inf]])
    padded_xp, padded_fp = np.concatenate([xp, [0.0, 0.0]]), np.concatenate([fp, [9.0, 9.0]])  # rows padded past n
    for x in xs:
        for left, right in ((fp[0], fp[-1]), (0.0, 0.0)):
            want = np.interp(x, xp, fp, left=left, right=right)
            got = interp_one(padded_xp, padded_fp, n, float(x), left, right)
            assert np.array_equal(np.float64(got), want, equal_nan=True), (x, got, want)
            assert np.signbit(got) == np.signbit(want)


def test_interp_one_of_a_single_point_is_its_value_or_the_ends():
    xp, fp = np.array([0.5]), np.array([2.0])
    assert interp_one(xp, fp, 1, 0.5, -1.0, 1.0) == np.interp(0.5, xp, fp, left=-1.0, right=1.0) == 2.0
    assert interp_one(xp, fp, 1, 0.4, -1.0, 1.0) == -1.0
    assert interp_one(xp, fp, 1, 0.6, -1.0, 1.0) == 1.0
