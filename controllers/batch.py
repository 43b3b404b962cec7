"""Arithmetic of batchable controllers: the same numbers for an episode whatever batch it runs in.

A batchable controller (:attr:`drillgym.controllers.base.Controller.batchable`) steps N episodes at once, one row
each. Its 3x3 matrix-vector products are written out as elementwise sums (:func:`matvec`): a BLAS product's rounding
may depend on the shapes it is given, an elementwise sum's never does, so an episode run alone and the same
episode run in a batch of 64 command identical actions. Units: those of the arguments.
"""

from __future__ import annotations

import numba
import numpy as np

from drillgym.envs.constants import ACTION_DIM, FEED_OVERRIDE_LOG2_MAX, MAX_CORRECTION_M


def matvec(m: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``m @ x`` of every row: ``m`` (3, 3) shared or (N, 3, 3) per row, ``x`` (N, 3); (N, 3).

    Each entry is ``(m[i, 0] x[0] + m[i, 1] x[1]) + m[i, 2] x[2]``, in that order (compiled, without fused
    multiply-adds: the numbers numpy's elementwise expression gives, ``tests/controllers/test_controller_batch.py``).
    """
    out = np.empty((len(x), 3))
    mm = np.asarray(m, dtype=np.float64)
    _matvec_rows(mm if mm.ndim == 3 else mm[None], np.asarray(x, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def _matvec_rows(m: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:  # pragma: no cover (compiled)
    """:func:`matvec` into ``out``; ``m`` (1, 3, 3) for a shared matrix or (N, 3, 3)."""
    shared = m.shape[0] == 1
    for n in range(x.shape[0]):
        a = m[0] if shared else m[n]
        x0, x1, x2 = x[n, 0], x[n, 1], x[n, 2]
        for i in range(3):
            out[n, i] = a[i, 0] * x0 + a[i, 1] * x1 + a[i, 2] * x2


def unscale_actions(correction_base_m: np.ndarray, feed_scale: np.ndarray | float = 1.0) -> np.ndarray:
    """:func:`drillgym.envs.constants.unscale_action` of every row: corrections (N, 3) m, feed scales (N,) or one.

    Returns the actions (N, 4), clipped to the action box, float32.
    """
    n = len(correction_base_m)
    a = np.empty((n, ACTION_DIM))
    a[:, :3] = correction_base_m / MAX_CORRECTION_M
    a[:, 3] = np.log2(np.maximum(feed_scale, 1e-9)) / FEED_OVERRIDE_LOG2_MAX
    return np.minimum(np.maximum(a, -1.0), 1.0).astype(np.float32)  # np.clip(a, -1, 1), without its wrapper


def window_mean(window: np.ndarray, step: int) -> np.ndarray:
    """Mean of a ring buffer's samples so far, oldest first, as ``np.mean`` over a deque of them sums them.

    ``window`` (W, N, k) holds sample ``j`` at ``j % W``; ``step`` is the newest sample's index. Returns (N, k).
    """
    size = window.shape[0]
    filled = min(step + 1, size)
    first = step + 1 - filled
    total = window[first % size].copy()
    for k in range(first + 1, step + 1):
        total += window[k % size]
    return total / filled
