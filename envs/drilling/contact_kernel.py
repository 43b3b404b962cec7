"""The tip balance's per-sample loop, compiled (numba): :meth:`TipContactSolver.run`'s arithmetic.

The physics is documented in :mod:`drillgym.envs.drilling.contact`; this module holds only its inner
loop over consecutive F/T samples, on plain arrays, so that an agent step's five samples cost one call.
"""

from __future__ import annotations

import numba
import numpy as np

from drillgym.envs.drilling.force_model import stage_of
from drillgym.envs.drilling.hole import cut

STATE_SIZE = 8
"""``state`` layout: rigid tip (3), true tip (3), deepest point cut ``bottom_z``, local depth ``d`` (m, task frame)."""
ROW_SIZE = 13
"""``rows`` layout: tip (3), rigid (3), force (3), torque about the axis, local depth, stage, cutting (0/1)."""


Mat = tuple[float, float, float, float, float, float, float, float, float]
"""A 3x3 matrix, row-major, as the loop passes it (no array to allocate)."""
_EYE: Mat = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)
_ZERO: Mat = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@numba.njit(cache=True)
def _guided(c: Mat, k: float) -> tuple[Mat, Mat, Mat]:  # pragma: no cover (compiled)
    """Balance matrices with lateral cut stiffness ``k`` (N/m) on x and y: ``M = (I + C K)⁻¹``, ``S = M C``, ``M C K``."""
    a00, a01, a02 = 1.0 + c[0] * k, 0.0 + c[1] * k, 0.0
    a10, a11, a12 = 0.0 + c[3] * k, 1.0 + c[4] * k, 0.0
    a20, a21, a22 = 0.0 + c[6] * k, 0.0 + c[7] * k, 1.0
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    m = (
        c00 / det, (a02 * a21 - a01 * a22) / det, (a01 * a12 - a02 * a11) / det,
        c01 / det, (a00 * a22 - a02 * a20) / det, (a02 * a10 - a00 * a12) / det,
        c02 / det, (a01 * a20 - a00 * a21) / det, (a00 * a11 - a01 * a10) / det,
    )  # fmt: skip
    s = (
        m[0] * c[0] + m[1] * c[3] + m[2] * c[6], m[0] * c[1] + m[1] * c[4] + m[2] * c[7],
        m[0] * c[2] + m[1] * c[5] + m[2] * c[8],
        m[3] * c[0] + m[4] * c[3] + m[5] * c[6], m[3] * c[1] + m[4] * c[4] + m[5] * c[7],
        m[3] * c[2] + m[4] * c[5] + m[5] * c[8],
        m[6] * c[0] + m[7] * c[3] + m[8] * c[6], m[6] * c[1] + m[7] * c[4] + m[8] * c[7],
        m[6] * c[2] + m[7] * c[5] + m[8] * c[8],
    )  # fmt: skip
    mck = (s[0] * k, s[1] * k, 0.0, s[3] * k, s[4] * k, 0.0, s[6] * k, s[7] * k, 0.0)
    return m, s, mck


@numba.njit(cache=True)
def run_samples(  # noqa: C901 (one loop, on purpose)
    targets: np.ndarray,
    servo_gain: float,
    state: np.ndarray,
    touching: bool,
    j: int,
    tan_beta: float,
    bounds: tuple[float, float, float, float],
    grid: np.ndarray,
    table: np.ndarray,
    compliance: np.ndarray,
    k_guided: float,
    centre_xy: np.ndarray,
    filled: np.ndarray,
    hole_bins: np.ndarray,
    bin_m: float,
    rows: np.ndarray,
) -> tuple[bool, int]:  # pragma: no cover (compiled)
    """Solve the balance for consecutive servo targets into ``rows``; returns ``(touching, j)``.

    Args:
        targets: (k, 3) servo targets (m, task frame).
        servo_gain: share of the way to its target the servo moves per sample.
        state: :data:`STATE_SIZE` floats, updated in place.
        touching: whether the tip touched bone at the last sample.
        j: the depth grid's bracket of the last root (a warm start).
        tan_beta: the surface slope (with skid relief).
        bounds: the stage bounds (m, :func:`~drillgym.envs.drilling.force_model.stage_bounds`).
        grid: the force table's depths (n,) (m).
        table: the force table's rows (n, 4): F_x, F_y, F_z (N), M_z (N·m), task axes.
        compliance: arm + drill compliance (3x3, m/N, task axes).
        k_guided: lateral cut stiffness (N/m) when the tip is inside the bone and touching.
        centre_xy: the hole's centreline per bin (m, task xy), updated in place.
        filled: the hole's cut bins, updated in place.
        hole_bins: the hole's ``[deepest_bin, first_bin]``, updated in place (:func:`~drillgym.envs.drilling.hole.cut`).
        bin_m: the hole's bin length (m).
        rows: (k, :data:`ROW_SIZE`) the samples' rows, written.
    """
    n = grid.shape[0]
    cm = compliance
    c = (cm[0, 0], cm[0, 1], cm[0, 2], cm[1, 0], cm[1, 1], cm[1, 2], cm[2, 0], cm[2, 1], cm[2, 2])
    m1, s1, k1 = _guided(c, k_guided)
    r0, r1, r2, p0, p1, p2, bottom, d = state
    touch = bounds[0]
    v_cur = -1
    m, s, mck, kx = _EYE, c, _ZERO, 0.0
    lam = 1.0
    torque = 0.0
    for row in range(targets.shape[0]):
        r0 += servo_gain * (targets[row, 0] - r0)
        r1 += servo_gain * (targets[row, 1] - r1)
        r2 += servo_gain * (targets[row, 2] - r2)
        v = 1 if touching and p2 + p0 * tan_beta > touch else 0
        if v != v_cur:
            v_cur = v
            if v == 1:
                m, s, mck, kx = m1, s1, k1, k_guided
            else:
                m, s, mck, kx = _EYE, c, _ZERO, 0.0
        b0 = m[0] * r0 + m[1] * r1 + m[2] * r2 + mck[0] * p0 + mck[1] * p1
        b1 = m[3] * r0 + m[4] * r1 + m[5] * r2 + mck[3] * p0 + mck[4] * p1
        b2 = m[6] * r0 + m[7] * r1 + m[8] * r2 + mck[6] * p0 + mck[7] * p1
        # depth: the stable root of d = front + tanβ (b0 + s_x · F(d)) on the piecewise-linear table
        front = max(bottom, p2)
        rhs = front + tan_beta * b0
        if tan_beta == 0.0:
            d = rhs
        else:
            j = min(max(j, 1), n - 1)
            for _ in range(4 * n):
                q0 = s[0] * table[j - 1, 0] + s[1] * table[j - 1, 1] + s[2] * table[j - 1, 2]
                q1 = s[0] * table[j, 0] + s[1] * table[j, 1] + s[2] * table[j, 2]
                h0 = grid[j - 1] - tan_beta * q0 - rhs
                h1 = grid[j] - tan_beta * q1 - rhs
                if h0 > 0.0:
                    if j == 1:
                        d = rhs + tan_beta * (s[0] * table[0, 0] + s[1] * table[0, 1] + s[2] * table[0, 2])
                        break
                    j -= 1
                elif h1 < 0.0:
                    if j == n - 1:
                        last = n - 1
                        d = rhs + tan_beta * (s[0] * table[last, 0] + s[1] * table[last, 1] + s[2] * table[last, 2])
                        break
                    j += 1
                else:
                    d = grid[j - 1] + (grid[j] - grid[j - 1]) * (-h0) / (h1 - h0) if h1 != h0 else grid[j - 1]
                    break
            else:
                raise RuntimeError("tip balance: no stable root found")
        # the table's row at d
        if d <= grid[0]:
            i, t = 1, 0.0
        elif d >= grid[n - 1]:
            i, t = n - 1, 1.0
        else:
            i = np.searchsorted(grid, d, side="right")
            t = (d - grid[i - 1]) / (grid[i] - grid[i - 1])
        a = i - 1
        f0 = table[a, 0] + t * (table[i, 0] - table[a, 0])
        f1 = table[a, 1] + t * (table[i, 1] - table[a, 1])
        f2 = table[a, 2] + t * (table[i, 2] - table[a, 2])
        tq = table[a, 3] + t * (table[i, 3] - table[a, 3])
        touching = f0 != 0.0 or f1 != 0.0 or f2 != 0.0
        sf0 = s[0] * f0 + s[1] * f1 + s[2] * f2
        sf1 = s[3] * f0 + s[4] * f1 + s[5] * f2
        sf2 = s[6] * f0 + s[7] * f1 + s[8] * f2
        full_z = b2 + sf2
        if not touching or full_z >= bottom:
            lam = 1.0
        elif b2 > bottom:
            lam = (b2 - bottom) / (b2 - full_z)
        else:
            lam = 0.0
        q0 = b0 + lam * sf0
        q1 = b1 + lam * sf1
        q2 = b2 + lam * sf2
        cutting = touching and lam >= 1.0 and q2 > bottom
        if cutting:
            bottom = q2
            cut(centre_xy, filled, hole_bins, bin_m, q2, q0, q1)
        torque = lam * tq
        out = rows[row]
        out[0], out[1], out[2] = q0, q1, q2
        out[3], out[4], out[5] = r0, r1, r2
        out[6] = lam * f0 + kx * (p0 - q0)
        out[7] = lam * f1 + kx * (p1 - q1)
        out[8] = lam * f2
        out[9] = torque
        out[10] = d
        out[11] = stage_of(d, bounds) if touching and lam > 0.0 else 0
        out[12] = 1.0 if cutting else 0.0
        p0, p1, p2 = q0, q1, q2
    state[0], state[1], state[2], state[3], state[4], state[5], state[6], state[7] = r0, r1, r2, p0, p1, p2, bottom, d
    return touching, j
