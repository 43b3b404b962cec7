"""``np.interp`` of one point, compiled, without the arrays numba's ``np.interp`` makes for a scalar.

The same arithmetic as NumPy's (and numba's) ``np.interp``: the bracket ``xp[j] <= x < xp[j + 1]``, the slope
``(f₁ − f₀) / (x₁ − x₀)`` times ``x − x₀`` plus ``f₀``, an exact grid point's value as tabulated, ``left`` below
the grid and ``right`` above it, NaN through; so every number is ``np.interp``'s bit for bit
(``tests/envs/test_interp_kernel.py``). ``xp`` must increase strictly.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def interp_one(
    xp: np.ndarray, fp: np.ndarray, n: int, x: float, left: float, right: float
) -> float:  # pragma: no cover
    """``np.interp(x, xp[:n], fp[:n], left=left, right=right)`` for one ``x``, as NumPy computes it."""
    if np.isnan(x):
        return x
    if x < xp[0]:
        return left
    if x > xp[n - 1]:
        return right
    if x == xp[n - 1]:
        return fp[n - 1]
    lo, hi = 0, n - 1  # the bracket xp[j] <= x < xp[j + 1]
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xp[mid] <= x:
            lo = mid
        else:
            hi = mid
    j = lo
    if xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    res = slope * (x - xp[j]) + fp[j]
    if np.isnan(res):  # numpy tries the other end
        res = slope * (x - xp[j + 1]) + fp[j + 1]
        if np.isnan(res) and fp[j] == fp[j + 1]:
            res = fp[j]
    return res
