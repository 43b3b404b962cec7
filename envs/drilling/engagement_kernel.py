"""The lips' engaged lengths over a depth grid, compiled: the geometric sums of the force tables.

:meth:`drillgym.envs.drilling.force_model.EngagementTable.build` needs, for every tip depth of its grid and for
each material (cortical, cancellous), which lip elements ``(r, φ)`` are in it and their summed lengths. With
numpy these are masks of shape (depths, radii, angles) and their sums; here each element's two changes of state are
found once, and a depth sums again only what changed there. The sums are added in numpy's own order (a sum over
the radii element by element, a sum along a contiguous row by numpy's pairwise summation, :func:`pairwise_sum`), so
every number equals the numpy computation's bit for bit (``tests/envs/test_engagement_kernel.py`` compares them on
random scenarios).

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
def _first_true(grid: np.ndarray, setback: float, bound: float, strict: bool) -> int:  # pragma: no cover (compiled)
    """The first index ``g`` of the ascending ``grid`` with ``grid[g] − setback > bound`` (``strict``) or ``≥ bound``.

    ``grid[g] − setback`` rounds monotonically in ``grid[g]``, so the condition holds from one index on (``grid.size``:
    never): a bisection finds it, with the very expression the element loop evaluates.
    """
    lo, hi = 0, grid.size
    while lo < hi:
        mid = (lo + hi) // 2
        e = grid[mid] - setback
        if (e > bound) if strict else (e >= bound):
            hi = mid
        else:
            lo = mid + 1
    return lo


@numba.njit(cache=True)
def _state_changes(
    grid: np.ndarray, setback: np.ndarray, layer_depth: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover (compiled)
    """When each element ``k = i Φ + j`` changes state along the grid, as events grouped by depth.

    An element enters the bone at the first depth with ``d − setback > 0`` and the cancellous bone at the first with
    ``d − setback ≥ layer_depth`` (at once where that comes first). Returns ``g_out`` (its cancellous depth index,
    at least its entry's), ``start`` (G + 2,) and ``events``: depth ``g``'s elements are
    ``events[start[g]:start[g + 1]]``, each at most twice in all.
    """
    n_g, n_p = grid.size, setback.shape[1]
    size = setback.size
    g_in = np.empty(size, dtype=np.int64)
    g_out = np.empty(size, dtype=np.int64)
    start = np.zeros(n_g + 2, dtype=np.int64)
    for k in range(size):
        sb = setback[k // n_p, k % n_p]
        g_in[k] = _first_true(grid, sb, 0.0, True)
        g_out[k] = max(g_in[k], _first_true(grid, sb, layer_depth, False))
        start[g_in[k] + 1] += 1
        if g_out[k] > g_in[k]:
            start[g_out[k] + 1] += 1
    for g in range(n_g + 1):
        start[g + 1] += start[g]
    fill = start[:-1].copy()
    events = np.empty(start[n_g + 1], dtype=np.int64)
    for k in range(size):
        events[fill[g_in[k]]] = k
        fill[g_in[k]] += 1
        if g_out[k] > g_in[k]:
            events[fill[g_out[k]]] = k
            fill[g_out[k]] += 1
    return g_out, start, events


@numba.njit(cache=True)
def _lip_columns(
    g: int,
    dirty: np.ndarray,
    state: np.ndarray,
    is_lip: np.ndarray,
    db: np.ndarray,
    r: np.ndarray,
    lip_phi: np.ndarray,
    lip_r_phi: np.ndarray,
    lip_len: np.ndarray,
    lip_moment: np.ndarray,
    same: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """Depth ``g``'s lip sums of both materials: the ``dirty`` angles summed again, the others depth ``g − 1``'s."""
    n_r, n_p = is_lip.size, dirty.size
    for mat in range(2):
        if g > 0:
            lip_phi[mat, g] = lip_phi[mat, g - 1]
        for j in range(n_p):
            if not dirty[j]:
                continue
            acc, acc_r = 0.0, 0.0  # numpy's sum over the radii of (mask & is_lip) * db: the engaged terms in order
            for i in range(n_r):
                if is_lip[i] and state[i * n_p + j] == mat + 1:
                    acc += db[i]
                    acc_r += db[i] * r[i]
            lip_phi[mat, g, j] = acc
            lip_r_phi[mat, j] = acc_r
        lip_len[mat, g] = pairwise_sum(lip_phi[mat, g], 0, n_p)
        lip_moment[mat, g] = pairwise_sum(lip_r_phi[mat], 0, n_p)
        same[mat, g] = g > 0 and np.array_equal(lip_phi[mat, g], lip_phi[mat, g - 1])


@numba.njit(cache=True)
def lip_sums(
    grid: np.ndarray, setback: np.ndarray, layer_depth: float, is_lip: np.ndarray, db: np.ndarray, r: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Engaged element sums at every depth of ``grid``.

    Args:
        grid: tip depths past the surface (m), (G,), ascending.
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
        ``same`` (2, G): whether depth ``g``'s ``lip_phi`` row of that material is depth ``g − 1``'s (False at 0);
        each material's sums as numpy's ``((mask & is_lip) * db[:, None]).sum(axis=1)`` and the like.

    An element's state (out of bone, cortex, cancellous bone) changes at most twice along the grid, at depths found
    by bisection with the element loop's own expression (:func:`_first_true`). Depth by depth, only the angles
    whose elements changed are summed again (over the radii, in order, as numpy sums a mask); the others, and every
    sum of a depth where nothing changed, are the previous depth's numbers, which the same sums of the same terms
    would give again.
    """
    n_g, n_r, n_p = grid.size, setback.shape[0], setback.shape[1]
    lip_engaged = np.zeros(n_g)
    lip_phi = np.zeros((2, n_g, n_p))
    lip_r_phi = np.zeros((2, n_p))  # the current depth's moments per angle
    lip_len = np.zeros((2, n_g))
    lip_moment = np.zeros((2, n_g))
    chisel_len = np.zeros((2, n_g))
    cut = np.zeros((2, n_g), dtype=np.bool_)
    same = np.zeros((2, n_g), dtype=np.bool_)
    size = n_r * n_p
    chisel_end = 0  # the chisel edge's radii come first (r < web radius), the lips' after them
    while chisel_end < n_r and not is_lip[chisel_end]:
        chisel_end += 1
    chisel_end *= n_p
    g_out, start, events = _state_changes(grid, setback, layer_depth)
    state = np.zeros(size, dtype=np.int64)  # 0: out of bone, 1: cortex, 2: cancellous
    count = np.zeros(3, dtype=np.int64)
    count[0] = size
    engaged_row = np.zeros(size)
    chisel_rows = np.zeros((2, size))
    dirty = np.ones(n_p, dtype=np.bool_)
    for g in range(n_g):
        lips_moved = chisel_moved = lips_changed = g == 0
        for e in range(start[g], start[g + 1]):
            k = events[e]
            i, old = k // n_p, state[k]
            new = 2 if g >= g_out[k] else 1
            state[k] = new
            count[old] -= 1
            count[new] += 1
            if is_lip[i]:
                engaged_row[k] = db[i]
                dirty[k % n_p] = True
                lips_moved = lips_moved or old == 0
                lips_changed = True
            else:
                if old > 0:
                    chisel_rows[old - 1, k] = 0.0
                chisel_rows[new - 1, k] = db[i]
                chisel_moved = True
        cut[0, g], cut[1, g] = count[1] > 0, count[2] > 0
        if lips_changed:
            _lip_columns(g, dirty, state, is_lip, db, r, lip_phi, lip_r_phi, lip_len, lip_moment, same)
            dirty[:] = False
        else:  # no lip element moved: the previous depth's sums
            lip_phi[:, g] = lip_phi[:, g - 1]
            lip_len[:, g], lip_moment[:, g] = lip_len[:, g - 1], lip_moment[:, g - 1]
            same[:, g] = True
        lip_engaged[g] = pairwise_sum(engaged_row, 0, size, chisel_end, size) if lips_moved else lip_engaged[g - 1]
        for mat in range(2):
            chisel_len[mat, g] = (
                pairwise_sum(chisel_rows[mat], 0, size, 0, chisel_end) if chisel_moved else chisel_len[mat, g - 1]
            )
    return lip_engaged, lip_phi, lip_len, lip_moment, chisel_len, cut, same
