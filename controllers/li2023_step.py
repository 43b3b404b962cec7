"""``li2023``'s per-step arithmetic for a batch, compiled: the offline correction, the y gain, the clips, the action.

Every agent step :meth:`Li2023Controller.act_batch <drillgym.controllers.li2023.Li2023Controller.act_batch>` turns
each episode's nominal depth and online correction into its action:

    offline = −P · R · C_tool · (F_x, F_y, 0)(depth)     (the offline force model, ``np.interp`` with 0 outside)
    total   = offline + online,  then the y gain along task y,  then clipped to ± max_correction
    action  = (total / MAX_CORRECTION_M, 0) clipped to [−1, 1], float32

:func:`actions_into` does it in one call for N episodes (the corrections in metres too, for tests and logs), with numpy's arithmetic term for term (the 3x3 products
in :func:`drillgym.controllers.batch.matvec`'s order, ``np.maximum``/``np.minimum``'s clip, the float32 cast), so
the actions are those of the numpy expressions it replaces, bit for bit
(``tests/controllers/test_li2023_step.py``). Units: SI; frames: base unless named.
"""

from __future__ import annotations

import numba
import numpy as np

from drillgym.envs.constants import MAX_CORRECTION_M
from drillgym.envs.interp_kernel import interp_one


@numba.njit(cache=True)
def _times(m: np.ndarray, x0: float, x1: float, x2: float) -> tuple[float, float, float]:  # pragma: no cover
    """``m @ x`` as :func:`~drillgym.controllers.batch.matvec` sums each row: ``(m₀ x₀ + m₁ x₁) + m₂ x₂``."""
    return (
        m[0, 0] * x0 + m[0, 1] * x1 + m[0, 2] * x2,
        m[1, 0] * x0 + m[1, 1] * x1 + m[1, 2] * x2,
        m[2, 0] * x0 + m[2, 1] * x1 + m[2, 2] * x2,
    )


@numba.njit(cache=True)
def _clip(x: float, lo: float, hi: float) -> float:  # pragma: no cover (compiled)
    """``np.minimum(np.maximum(x, lo), hi)`` for one float (NaN stays NaN)."""
    if not (x >= lo or x != x):
        x = lo
    if not (x <= hi or x != x):
        x = hi
    return x


@numba.njit(cache=True)
def _offline(
    i: int,
    k: int,
    depth_m: np.ndarray,
    xp: np.ndarray,
    fp: np.ndarray,
    sizes: np.ndarray,
    model_of: np.ndarray,
    lateral: np.ndarray,
    rot: np.ndarray,
    c_tool: np.ndarray,
) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """Row ``i``'s offline correction ``−P (R (C (F_x, F_y, 0)))`` (m, base), with matrices ``k`` (0 when shared)."""
    m = model_of[i]
    f0 = interp_one(xp[m], fp[m, :, 0], sizes[m], depth_m[i], 0.0, 0.0)
    f1 = interp_one(xp[m], fp[m, :, 1], sizes[m], depth_m[i], 0.0, 0.0)
    a0, a1, a2 = _times(c_tool[k], f0, f1, 0.0)
    b0, b1, b2 = _times(rot[k], a0, a1, a2)
    c0, c1, c2 = _times(lateral[k], b0, b1, b2)
    return -c0, -c1, -c2


@numba.njit(cache=True)
def offline_into(
    depth_m: np.ndarray,
    xp: np.ndarray,
    fp: np.ndarray,
    sizes: np.ndarray,
    model_of: np.ndarray,
    lateral: np.ndarray,
    rot: np.ndarray,
    c_tool: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """Each row's offline correction alone into ``out`` (N, 3) (m, base frame); arguments as :func:`actions_into`'s."""
    shared = lateral.shape[0] == 1
    for i in range(depth_m.shape[0]):
        out[i, 0], out[i, 1], out[i, 2] = _offline(
            i, 0 if shared else i, depth_m, xp, fp, sizes, model_of, lateral, rot, c_tool
        )


@numba.njit(cache=True)
def actions_into(
    depth_m: np.ndarray,
    offline_on: bool,
    xp: np.ndarray,
    fp: np.ndarray,
    sizes: np.ndarray,
    model_of: np.ndarray,
    lateral: np.ndarray,
    rot: np.ndarray,
    c_tool: np.ndarray,
    online_base_m: np.ndarray,
    y_gain: np.ndarray,
    y_any: bool,
    y_all: bool,
    max_correction_m: float,
    correction_base_m: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """Each episode's correction into ``correction_base_m`` (N, 3) and its action into ``out`` (N, 4) float32.

    Args:
        depth_m: (N,) nominal depths (m; the observation's float32, widened).
        offline_on: add the offline correction (else it is 0).
        xp: the offline models' depth grids (M, L) (m), as
            :class:`~drillgym.controllers.stacked_models.StackedOfflineModels` holds them.
        fp: their lateral force tables (M, L, 2) (N, task x and y).
        sizes: (M,) each grid's length.
        model_of: (N,) each episode's model.
        lateral: the projector across the drill (base frame): (1, 3, 3) shared or (N, 3, 3) per episode.
        rot: ``R_base_task``, likewise.
        c_tool: the drill's compliance (m/N, task axes), likewise.
        online_base_m: (N, 3) the online correction the robot has reached (m).
        y_gain: (1,) shared or (N,) the gain along task y.
        y_any: whether any y gain differs from 1.
        y_all: whether every one does.
        max_correction_m: the clip on each axis of the total correction (m).
        correction_base_m: (N, 3) the clipped total correction (m, base frame), written.
        out: (N, 4) float32, the actions, written.
    """
    shared_m = lateral.shape[0] == 1
    shared_y = y_gain.shape[0] == 1
    for i in range(depth_m.shape[0]):
        k = 0 if shared_m else i
        t0, t1, t2 = 0.0, 0.0, 0.0
        if offline_on:
            t0, t1, t2 = _offline(i, k, depth_m, xp, fp, sizes, model_of, lateral, rot, c_tool)
        t0, t1, t2 = t0 + online_base_m[i, 0], t1 + online_base_m[i, 1], t2 + online_base_m[i, 2]
        g = y_gain[0] if shared_y else y_gain[i]
        if y_any and (y_all or g != 1.0):  # total + (g - 1) (total · y) y, y the task's y axis in base
            y0, y1, y2 = rot[k, 0, 1], rot[k, 1, 1], rot[k, 2, 1]
            along = (g - 1.0) * (t0 * y0 + t1 * y1 + t2 * y2)
            t0, t1, t2 = t0 + along * y0, t1 + along * y1, t2 + along * y2
        lim = max_correction_m
        correction_base_m[i, 0] = t0 = _clip(t0, -lim, lim)
        correction_base_m[i, 1] = t1 = _clip(t1, -lim, lim)
        correction_base_m[i, 2] = t2 = _clip(t2, -lim, lim)
        out[i, 0] = _clip(t0 / MAX_CORRECTION_M, -1.0, 1.0)
        out[i, 1] = _clip(t1 / MAX_CORRECTION_M, -1.0, 1.0)
        out[i, 2] = _clip(t2 / MAX_CORRECTION_M, -1.0, 1.0)
        out[i, 3] = 0.0  # log2 of the feed scale 1, over the feed's span


@numba.njit(cache=True)
def online_into(
    times_s: np.ndarray, corrections: np.ndarray, ring: np.ndarray, t: float, point_period_s: float, out: np.ndarray
) -> None:  # pragma: no cover (compiled)
    """The online correction the robot has reached at time ``t`` (s), moving linearly between corrected points.

    The points are a ring (queue) of ``ring[1]`` entries from slot ``ring[0]`` on: each a time (s) in ``times_s``
    (P,) and each episode's correction (m, base) in ``corrections`` (P, N, 3). Points the time has passed are
    dropped first (while the second is due, the first goes). The point before the next one is reached at the
    previous point's time: before ``t₁ − period`` the correction is the first point's, then
    ``c₀ + (c₁ − c₀)(t − t_start) / (t₁ − t_start)`` elementwise (numpy's operations in numpy's order). Writes ``out``
    (N, 3).
    """
    size = times_s.shape[0]
    while ring[1] >= 2 and times_s[(ring[0] + 1) % size] <= t:
        ring[0] = (ring[0] + 1) % size
        ring[1] -= 1
    first = ring[0]
    c0 = corrections[first]
    t0 = times_s[first]
    if ring[1] == 1 or t <= t0:
        out[:] = c0
        return
    second = (first + 1) % size
    t1 = times_s[second]
    c1 = corrections[second]
    t_start = t1 - point_period_s
    if t <= t_start:
        out[:] = c0
        return
    span, dt = t1 - t_start, t - t_start
    for i in range(out.shape[0]):
        for k in range(3):
            out[i, k] = c0[i, k] + (c1[i, k] - c0[i, k]) * dt / span
