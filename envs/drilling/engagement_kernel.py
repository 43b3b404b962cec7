"""The lips' engaged lengths over a depth grid, compiled: the geometric sums of the force tables.

:meth:`drillgym.envs.drilling.force_model.EngagementTable.build` needs, for every tip depth of its grid and for
each material (cortical, cancellous), which lip elements ``(r, φ)`` are in it and their summed lengths. With
numpy these are masks of shape (depths, radii, angles) and their sums; here one loop visits each element once,
without the masks. The sums are added in numpy's own order (a sum over the radii element by element, a sum along
a contiguous row by numpy's pairwise summation, :func:`pairwise_sum`), so every number equals the numpy
computation's bit for bit (``tests/envs/test_force_model.py`` compares them on random scenarios).

Units: lengths in m, first moments in m².
"""

from __future__ import annotations

import numba
import numpy as np

CORTICAL, CANCELLOUS = 0, 1
"""Material index of the per-material outputs."""


@numba.njit(cache=True)
def _block_sum(a: np.ndarray, lo: int, n: int) -> float:  # pragma: no cover (compiled)
    """The sum numpy gives a row of at most 128: in order below 8, else eight running sums combined pairwise, then the rest."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    whole = n - n % 8
    while i < whole:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@numba.njit(cache=True)
def pairwise_sum(a: np.ndarray, lo: int, n: int, first: int = 0, end: int = -1) -> float:  # pragma: no cover
    """``a[lo:lo + n].sum()`` as numpy adds a contiguous float64 row (its pairwise summation, bit for bit).

    Rows of at most 128 are one block (:func:`_block_sum`); a longer one is the sum of its two halves (the first
    a multiple of 8 long), each summed the same way. The recursion runs on an explicit stack (a compiled recursive
    function does not load reliably from numba's cache). ``a`` is known to be +0 outside ``[first, end)`` (``end``
    -1: its length): a half that lies wholly outside sums to +0 without being read, and adding +0 to a sum leaves it
    exactly as it is, so the result is the same.
    """
    if end < 0:
        end = a.size
    if n <= 128:
        return _block_sum(a, lo, n)
    depth = 64
    f_lo = np.empty(depth, dtype=np.int64)
    f_n = np.empty(depth, dtype=np.int64)
    f_phase = np.zeros(depth, dtype=np.int64)
    f_left = np.zeros(depth)
    top = 0
    f_lo[0], f_n[0], f_phase[0] = lo, n, 0
    value = 0.0
    while top >= 0:
        m = f_n[top]
        half = m // 2
        half -= half % 8
        if f_phase[top] == 0 and (f_lo[top] + m <= first or f_lo[top] >= end):  # a half of zeros
            value = 0.0
            top -= 1
        elif m <= 128:
            value = _block_sum(a, f_lo[top], m)
            top -= 1
        elif f_phase[top] == 0:  # sum the first half
            f_phase[top] = 1
            top += 1
            f_lo[top], f_n[top], f_phase[top] = f_lo[top - 1], half, 0
        elif f_phase[top] == 1:  # keep it, sum the second half
            f_left[top] = value
            f_phase[top] = 2
            top += 1
            f_lo[top], f_n[top], f_phase[top] = f_lo[top - 1] + half, m - half, 0
        else:
            value = f_left[top] + value
            top -= 1
    return value


@numba.njit(cache=True)
def lip_sums(
    grid: np.ndarray, setback: np.ndarray, layer_depth: float, is_lip: np.ndarray, db: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Engaged element sums at every depth of ``grid``.

    Args:
        grid: tip depths past the surface (m), (G,).
        setback: how far each element ``(r, φ)`` sits above the tip along the axis, from the surface (m), (R, Φ):
            an element is in bone where ``d − setback > 0``, in the cortex while that is also ``< layer_depth``.
        layer_depth: the cortex's thickness along the axis (m).
        is_lip: whether each radius is on a lip (else the chisel edge), (R,).
        db: each radial element's edge length (m), (R,).
        r: each radial element's radius (m), (R,).

    Returns:
        ``lip_engaged`` (G,): engaged lip length, both materials (m);
        ``lip_phi`` (2, G, Φ): engaged lip length per angle and material (m);
        ``lip_len`` (2, G): its sum over the angles (m);
        ``lip_moment`` (2, G): the engaged lip's first moment about the axis (m²), summed per angle, then over them;
        ``chisel_len`` (2, G): engaged chisel-edge length (m);
        ``cut`` (2, G): whether any element is in that material;
        each material's sums as numpy's ``((mask & is_lip) * db[:, None]).sum(axis=1)`` and the like.
    """
    n_g, n_r, n_p = grid.size, setback.shape[0], setback.shape[1]
    lip_engaged = np.zeros(n_g)
    lip_phi = np.zeros((2, n_g, n_p))
    lip_r_phi = np.zeros((2, n_g, n_p))
    lip_len = np.zeros((2, n_g))
    lip_moment = np.zeros((2, n_g))
    chisel_len = np.zeros((2, n_g))
    cut = np.zeros((2, n_g), dtype=np.bool_)
    size = n_r * n_p
    engaged_row = np.zeros(size)
    chisel_rows = np.zeros((2, size))
    chisel_end = 0  # the chisel edge's radii come first (r < web radius), the lips' after them
    while chisel_end < n_r and not is_lip[chisel_end]:
        chisel_end += 1
    chisel_end *= n_p
    for g in range(n_g):
        d = grid[g]
        engaged_row[chisel_end:] = 0.0
        chisel_rows[:, :chisel_end] = 0.0
        cut_any = np.zeros(2, dtype=np.bool_)
        for i in range(n_r):
            row = setback[i]
            length, moment = db[i], db[i] * r[i]
            base = i * n_p
            for j in range(n_p):
                e = d - row[j]
                if e <= 0.0:
                    continue
                m = CORTICAL if e < layer_depth else CANCELLOUS
                cut_any[m] = True
                if is_lip[i]:  # adding 0.0 leaves a sum exactly as it is: only the engaged elements are added
                    engaged_row[base + j] = length
                    lip_phi[m, g, j] += length
                    lip_r_phi[m, g, j] += moment
                else:
                    chisel_rows[m, base + j] = length
        cut[0, g], cut[1, g] = cut_any[0], cut_any[1]
        lip_engaged[g] = pairwise_sum(engaged_row, 0, size, chisel_end, size)
        for mat in range(2):
            chisel_len[mat, g] = pairwise_sum(chisel_rows[mat], 0, size, 0, chisel_end)
            lip_len[mat, g] = pairwise_sum(lip_phi[mat, g], 0, n_p)
            lip_moment[mat, g] = pairwise_sum(lip_r_phi[mat, g], 0, n_p)
    return lip_engaged, lip_phi, lip_len, lip_moment, chisel_len, cut
