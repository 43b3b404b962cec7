"""Quasi-static tip balance at the bone, one solve per F/T sample (pure Python floats, fast).

Each update finds the tip position ``p`` (task frame) where the cutting force, the bone around the tip
and the elastic arm + drill balance:

    p = c + C · (F_cut(d(p)) + K_cut · (p_prev − p))

``c``: the rigid tip the servo holds; ``C``: arm + drill compliance (3x3, task axes); ``d(p) = z + x tan β``:
the tip depth below the local surface, so a tip skidding downhill loses engagement and one pushed
uphill gains it; ``K_cut = (K_lat / Δz) · s² · diag(1, 1, 0)``: to move sideways by Δp while advancing
Δz, the drill must cut the side of its own hole, which takes a force ``K_lat · s² · Δp / Δz``, with ``s``
the share of the lips' length in bone. An entering drill, barely engaged, skids down the slope; as it
bites it is caught, and once fully inside (s = 1) the hole copies its deviation forward, relaxing only
over ``K_lat / k`` of depth: an early deviation is locked in. The lateral feedback is solved implicitly
(its loop gain exceeds 1 at Li's operating point): ``d`` is the stable root of
``d = z_front + tan β · x(d)`` on the piecewise-linear force table.

Contact with the bottom of the hole is unilateral: the tip cannot pass the deepest point cut without
cutting. If the arm pushes it there against the full cutting force it cuts and the bottom advances;
if it pushes less, the tip rests on the bottom with a scaled-down force; pulled back, contact is lost.
``C`` and ``s`` are refreshed once per agent step (50 ms, ≤ 0.2 mm of feed).
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drillgym.envs.drilling.force_model import EngagementTable, stage_bounds, stage_of
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.drilling.hole import Hole

SampleRow = tuple[
    tuple[float, float, float], tuple[float, float, float], tuple[float, float, float], float, float, int, bool
]
"""One sample as a plain tuple: the fields of :class:`ContactSample`, in order."""


@dataclass
class ContactSample:
    """One update of the balance (task frame, SI)."""

    tip: tuple[float, float, float]
    rigid: tuple[float, float, float]
    force: tuple[float, float, float]
    torque_axis: float
    depth_local: float
    stage: int
    cutting: bool


class TipContactSolver:
    """Solves the tip balance for one scenario; holds the cut-state (bottom, hole)."""

    def __init__(
        self,
        table: EngagementTable,
        geometry: DrillGeometry,
        beta_rad: float,
        hole: Hole,
        lateral_cut_resistance_n: float,
        guidance_exponent: float = 1.0,
        skid_relief: float = 1.0,
        wall_guidance_floor: float = 1.0,
        wall_length_m: float = 0.5e-3,
    ) -> None:
        self.table = table
        self.geometry = geometry
        self.beta_rad = beta_rad
        self.tan_beta = skid_relief * math.tan(beta_rad)
        self.hole = hole
        self.k_lat_n = lateral_cut_resistance_n
        self.guidance_exponent = guidance_exponent
        if not 0.0 < wall_guidance_floor <= 1.0 or not wall_length_m > 0.0:
            raise ValueError(
                f"wall_guidance_floor={wall_guidance_floor} must be in (0, 1] and wall_length_m={wall_length_m} > 0"
            )
        self.wall_floor = wall_guidance_floor
        self.wall_length_m = wall_length_m
        self.grid = table.depth_m.tolist()
        self._bounds = stage_bounds(geometry, beta_rad)
        self._key: tuple[float, float] = (math.nan, math.nan)
        self.force_scale = 1.0
        """Per-specimen multiplier on every cutting force (bone variability), set before an episode."""
        self.clear_effects()
        self.reset((0.0, 0.0, -3e-3))

    def clear_effects(self) -> None:
        """No depth profile, nominal side guidance (see :meth:`set_depth_profile`, ``guidance_hook``)."""
        self.depth_profile: np.ndarray | None = None
        self.guidance_hook: Callable[[float, float], float] | None = None
        """Unmodelled effects: ``(engaged share, nominal guidance) -> guidance`` of the tip by the bone."""
        self._key = (math.nan, math.nan)

    def set_depth_profile(self, factor: np.ndarray | None) -> None:
        """Multiply the cutting forces by ``factor`` at each depth of the table grid (``table.depth_m``)."""
        if factor is not None:
            factor = np.asarray(factor, dtype=float)
            if factor.shape != self.table.depth_m.shape:
                raise ValueError(
                    f"depth profile has shape {factor.shape}; the table grid has {self.table.depth_m.shape}"
                )
        self.depth_profile = factor
        self._key = (math.nan, math.nan)

    def reset(self, start: tuple[float, float, float]) -> None:
        """Uncut bone; rigid and true tip at ``start``."""
        self.hole.reset()
        self.bottom_z = -math.inf
        self.rigid = list(start)
        self.tip = list(start)
        self.force = [0.0, 0.0, 0.0]
        self.torque = 0.0
        self.depth_local = start[2] + start[0] * self.tan_beta
        self.touching = False
        self._j = 1

    # ------------------------------------------------------------------ per agent step
    def prepare(self, compliance_m_n: np.ndarray, chip_m: float, advance_per_update_m: float) -> None:
        """Freeze compliance (m/N), chip (m) and the expected axial advance per update (m)."""
        if (chip_m, self.force_scale) != self._key:
            self._key = (chip_m, self.force_scale)
            rows = self.force_scale * (self.table.edge + chip_m * self.table.per_chip)
            if self.depth_profile is not None:
                rows = rows * self.depth_profile[:, None]
            self._rows = rows
            self._fx, self._fy, self._fz, self._mz = (rows[:, i].tolist() for i in range(4))
        self._c = np.asarray(compliance_m_n, dtype=float)
        share = float(np.interp(self.depth_local, self.table.depth_m, self.table.engaged_fraction))
        self._g = share**self.guidance_exponent * self._wall_factor()
        if self.guidance_hook is not None:
            self._g = self.guidance_hook(share, self._g)
        self._k_cut = self.k_lat_n / max(advance_per_update_m, 1e-7)
        self._variants: dict[int, tuple] = {}

    def _wall_factor(self) -> float:
        """Share of full guidance the hole's wall gives: the floor until the full diameter is in, 1 a wall later."""
        if self.wall_floor >= 1.0:
            return 1.0
        wall = min(max((self.depth_local - self._bounds[3]) / self.wall_length_m, 0.0), 1.0)
        return self.wall_floor + (1.0 - self.wall_floor) * wall

    def _get_variant(self, v: int) -> tuple:
        """0: free (out of the bone); 1: guided by the bone around the tip (built lazily)."""
        if v not in self._variants:
            k, g = self._k_cut, self._g
            kx, ky = ((0.0, 0.0), (k * g, k * g))[v]
            self._variants[v] = self._variant(self._c, kx, ky)
        return self._variants[v]

    @staticmethod
    def _variant(c: np.ndarray, kx: float, ky: float) -> tuple:
        """Matrices of the balance with lateral cut stiffnesses ``kx``, ``ky`` (N/m), as Python floats."""
        kc = np.diag([kx, ky, 0.0])
        m = _inv3(np.eye(3) + c @ kc)
        s = m @ c
        mck = s @ kc
        return m.tolist(), s.tolist(), mck.tolist(), (kx, ky)

    # ------------------------------------------------------------------ per F/T sample
    def update(self, target: tuple[float, float, float], servo_gain: float) -> ContactSample:
        """Move the servo toward ``target`` (gain in (0, 1]) and solve the balance."""
        r = self.rigid
        for i in range(3):
            r[i] += servo_gain * (target[i] - r[i])
        prev = self.tip
        inside = prev[2] + prev[0] * self.tan_beta > self._bounds[0]  # the tip itself is below the surface
        v = 1 if self.touching and inside else 0
        sol = self._solve(self._get_variant(v))
        tip, force, lam, d, touching, torque = sol
        cutting = touching and lam >= 1.0 and tip[2] > self.bottom_z
        if cutting:
            self.bottom_z = tip[2]
            self.hole.record(tip[2], np.array(tip[:2]))
        self.tip = tip
        self.force = force
        self.torque = lam * torque
        self.depth_local = d
        self.touching = touching
        stage = stage_of(d, self._bounds) if touching and lam > 0.0 else 0
        return ContactSample(
            (tip[0], tip[1], tip[2]),
            (r[0], r[1], r[2]),
            (force[0], force[1], force[2]),
            self.torque,
            d,
            stage,
            cutting,
        )

    def run(self, targets: list[tuple[float, float, float]], servo_gain: float) -> list[SampleRow]:  # noqa: C901 (one loop, on purpose)
        """Samples of consecutive targets (task frame, m): the same as :meth:`update` per target, fused.

        One pass with the state in local variables (the per-sample path of an agent step); the
        arithmetic is :meth:`update`'s, operation for operation, so the results are bit-identical
        (``tests/envs/test_contact_fused.py``). Rows are ``(tip, rigid, force, torque_axis, depth_local,
        stage, cutting)``, the fields of :class:`ContactSample`.
        """
        out: list[SampleRow] = []
        r0, r1, r2 = self.rigid
        p0, p1, p2 = self.tip
        tb = self.tan_beta
        bounds = self._bounds
        touch = bounds[0]
        bottom = self.bottom_z
        touching = self.touching
        grid = self.grid
        n = len(grid)
        fx, fy, fz, mz = self._fx, self._fy, self._fz, self._mz
        hole = self.hole
        bin_m = hole.bin_m
        g = servo_gain
        v_cur = -1
        m00 = m01 = m02 = m10 = m11 = m12 = m20 = m21 = m22 = 0.0
        s00 = s01 = s02 = s10 = s11 = s12 = s20 = s21 = s22 = 0.0
        k00 = k01 = k10 = k11 = k20 = k21 = kx = ky = 0.0
        j = self._j
        lam = 1.0
        torque = 0.0
        d = self.depth_local
        for t0, t1, t2 in targets:
            r0 += g * (t0 - r0)
            r1 += g * (t1 - r1)
            r2 += g * (t2 - r2)
            v = 1 if touching and p2 + p0 * tb > touch else 0
            if v != v_cur:
                v_cur = v
                m, s, mck, (kx, ky) = self._get_variant(v)
                (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = m
                (s00, s01, s02), (s10, s11, s12), (s20, s21, s22) = s
                (k00, k01, _), (k10, k11, _), (k20, k21, _) = mck
            b0 = m00 * r0 + m01 * r1 + m02 * r2 + k00 * p0 + k01 * p1
            b1 = m10 * r0 + m11 * r1 + m12 * r2 + k10 * p0 + k11 * p1
            b2 = m20 * r0 + m21 * r1 + m22 * r2 + k20 * p0 + k21 * p1
            # depth: the stable root of d = front + tanβ (b0 + s_x · F(d)), as _solve_depth
            front = max(bottom, p2)
            rhs = front + tb * b0
            if tb == 0.0:
                d = rhs
            else:
                j = min(max(j, 1), n - 1)
                for _ in range(4 * n):
                    d0, d1 = grid[j - 1], grid[j]
                    h0 = d0 - tb * (s00 * fx[j - 1] + s01 * fy[j - 1] + s02 * fz[j - 1]) - rhs
                    h1 = d1 - tb * (s00 * fx[j] + s01 * fy[j] + s02 * fz[j]) - rhs
                    if h0 > 0.0:
                        if j == 1:
                            d = rhs + tb * (s00 * fx[0] + s01 * fy[0] + s02 * fz[0])
                            break
                        j -= 1
                    elif h1 < 0.0:
                        if j == n - 1:
                            d = rhs + tb * (s00 * fx[n - 1] + s01 * fy[n - 1] + s02 * fz[n - 1])
                            break
                        j += 1
                    else:
                        d = d0 + (d1 - d0) * (-h0) / (h1 - h0) if h1 != h0 else d0
                        break
                else:  # pragma: no cover
                    raise RuntimeError("tip balance: no stable root found")
            # table row at d, as _row
            if d <= grid[0]:
                i, t = 1, 0.0
            elif d >= grid[-1]:
                i, t = n - 1, 1.0
            else:
                i = bisect.bisect_right(grid, d)
                t = (d - grid[i - 1]) / (grid[i] - grid[i - 1])
            a = i - 1
            f0 = fx[a] + t * (fx[i] - fx[a])
            f1 = fy[a] + t * (fy[i] - fy[a])
            f2 = fz[a] + t * (fz[i] - fz[a])
            tq = mz[a] + t * (mz[i] - mz[a])
            touching = f0 != 0.0 or f1 != 0.0 or f2 != 0.0
            sf0 = s00 * f0 + s01 * f1 + s02 * f2
            sf1 = s10 * f0 + s11 * f1 + s12 * f2
            sf2 = s20 * f0 + s21 * f1 + s22 * f2
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
            force = (lam * f0 + kx * (p0 - q0), lam * f1 + ky * (p1 - q1), lam * f2)
            cutting = touching and lam >= 1.0 and q2 > bottom
            if cutting:
                bottom = q2
                if int(q2 / bin_m) > hole.deepest_bin:
                    hole.record(q2, np.array([q0, q1]))
            torque = lam * tq
            stage = stage_of(d, bounds) if touching and lam > 0.0 else 0
            p0, p1, p2 = q0, q1, q2
            out.append(((q0, q1, q2), (r0, r1, r2), force, torque, d, stage, cutting))
        if out:
            self._j = j
            self.rigid = [r0, r1, r2]
            self.tip = [p0, p1, p2]
            self.force = list(out[-1][2])
            self.torque = torque
            self.depth_local = d
            self.touching = touching
            self.bottom_z = bottom
        return out

    def _solve(self, variant: tuple) -> tuple[list[float], list[float], float, float, bool, float]:
        m, s, mck, (kx, ky) = variant
        r, prev = self.rigid, self.tip
        base = [
            m[i][0] * r[0] + m[i][1] * r[1] + m[i][2] * r[2] + mck[i][0] * prev[0] + mck[i][1] * prev[1]
            for i in range(3)
        ]
        front = max(self.bottom_z, prev[2])
        d = self._solve_depth(front, base[0], s[0])
        f, torque = self._row(d)
        touching = f[0] != 0.0 or f[1] != 0.0 or f[2] != 0.0
        sf = [s[i][0] * f[0] + s[i][1] * f[1] + s[i][2] * f[2] for i in range(3)]
        full_z = base[2] + sf[2]
        if not touching or full_z >= self.bottom_z:
            lam = 1.0
        elif base[2] > self.bottom_z:
            lam = (base[2] - self.bottom_z) / (base[2] - full_z)
        else:
            lam = 0.0
        tip = [base[i] + lam * sf[i] for i in range(3)]
        force = [lam * f[0] + kx * (prev[0] - tip[0]), lam * f[1] + ky * (prev[1] - tip[1]), lam * f[2]]
        return tip, force, lam, d, touching, torque

    def _row(self, d: float) -> tuple[tuple[float, float, float], float]:
        grid = self.grid
        n = len(grid)
        if d <= grid[0]:
            j, t = 1, 0.0
        elif d >= grid[-1]:
            j, t = n - 1, 1.0
        else:
            j = bisect.bisect_right(grid, d)
            t = (d - grid[j - 1]) / (grid[j] - grid[j - 1])
        fx, fy, fz, mz = self._fx, self._fy, self._fz, self._mz
        a = j - 1
        return (
            (fx[a] + t * (fx[j] - fx[a]), fy[a] + t * (fy[j] - fy[a]), fz[a] + t * (fz[j] - fz[a])),
            mz[a] + t * (mz[j] - mz[a]),
        )

    def _solve_depth(self, front_z: float, base_x: float, s_x: list[float]) -> float:
        """Stable root of h(d) = d - tanβ · q(d) - (front_z + tanβ · base_x).

        ``q(d) = s_x · F(d)`` is the tip's x-shift under the table force at depth d (piecewise linear).
        """
        tb = self.tan_beta
        rhs = front_z + tb * base_x
        if tb == 0.0:
            return rhs
        fx, fy, fz = self._fx, self._fy, self._fz
        a, b, c = s_x

        def q(i: int) -> float:
            return a * fx[i] + b * fy[i] + c * fz[i]

        grid = self.grid
        n = len(grid)
        j = min(max(self._j, 1), n - 1)
        for _ in range(4 * n):
            d0, d1 = grid[j - 1], grid[j]
            h0 = d0 - tb * q(j - 1) - rhs
            h1 = d1 - tb * q(j) - rhs
            if h0 > 0.0:
                if j == 1:
                    self._j = 1
                    return rhs + tb * q(0)  # above the grid: no force there, q constant
                j -= 1
            elif h1 < 0.0:
                if j == n - 1:
                    self._j = j
                    return rhs + tb * q(n - 1)
                j += 1
            else:
                self._j = j
                return d0 + (d1 - d0) * (-h0) / (h1 - h0) if h1 != h0 else d0
        raise RuntimeError("tip balance: no stable root found")  # pragma: no cover


def _inv3(a: np.ndarray) -> np.ndarray:
    """Inverse of a 3x3 matrix by cofactors (faster than LAPACK at this size)."""
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = a.tolist()
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    return (
        np.array(
            [
                [c00, a02 * a21 - a01 * a22, a01 * a12 - a02 * a11],
                [c01, a00 * a22 - a02 * a20, a02 * a10 - a00 * a12],
                [c02, a01 * a20 - a00 * a21, a00 * a11 - a01 * a10],
            ]
        )
        / det
    )
