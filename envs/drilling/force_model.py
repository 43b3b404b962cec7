"""Cycle-averaged mechanistic drilling forces on an inclined surface (Li et al. 2023 §2.1).

Tool frame: z along the drill axis toward the bone, x in the plane of inclination pointing uphill
(the side of the surface that meets the drill first), y = z × x. The surface is the plane
``z = -x tan β`` through the planned entry point, so a lip point at radius ``r`` and angle ``φ`` (from +x)
lies ``e = d - r (cot κ - cos φ tan β)`` below the surface when the tip is a depth ``d`` past it.

Element forces on the tool (the spindle turns about +z, a right-hand drill seen from the chuck):

* tangential ``(K_tc h + K_te) db`` opposing the lip velocity ``(-sin φ, cos φ)``,
* thrust ``(K_fc h + K_fe) db`` along -z,
* radial ``(K_rc h + K_re) db`` toward the axis (the cone face is pushed back and in),

with ``db = dr / sin κ``. The chisel edge (r < w) indents: thrust only. The spindle turns at ~333 Hz,
far faster than the 100 Hz F/T, so forces are averaged over a revolution: each radius contributes
the sum over the angles at which it is in bone. On an arc symmetric about φ = 0 the sin terms cancel
and the net lateral force is ∝ ∫cos φ dφ over the engaged arc: the unbalance of Li's stages 1–3 comes
out of the geometry, not out of a script. Forces are linear in the chip h, so the model is tabulated
once per scenario as ``F(d) = A(d) + h B(d)`` and interpolated at run time.
"""

from __future__ import annotations

import bisect
import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from drillgym.envs.drilling.bone import BonePreset
from drillgym.envs.drilling.engagement_kernel import lip_sums
from drillgym.envs.drilling.geometry import DrillGeometry

N_RADIAL = 24
"""Radial elements along each lip (chisel included)."""
N_ANGULAR = 120
"""Angular samples per revolution for the cycle average."""


def engaged_corner_fraction(depth_m: float, geometry: DrillGeometry, beta_rad: float) -> float:
    """Fraction of a revolution over which the outer lip corner (r = R) is in bone, in [0, 1]."""
    r = geometry.radius_m
    tan_b = math.tan(abs(beta_rad))
    if tan_b < 1e-12:
        return 1.0 if depth_m >= r * geometry.cot_kappa else 0.0
    c_star = (geometry.cot_kappa - depth_m / r) / tan_b
    if c_star >= 1.0:
        return 0.0
    if c_star <= -1.0:
        return 1.0
    return math.acos(c_star) / math.pi


def stage_bounds(geometry: DrillGeometry, beta_rad: float) -> tuple[float, float, float, float]:
    """Tip depths (m) where Li's stages begin: first touch, corner in (stage 2), half (3), full (4)."""
    r, cot_k, tan_b = geometry.radius_m, geometry.cot_kappa, math.tan(abs(beta_rad))
    return min(0.0, r * (cot_k - tan_b)), r * (cot_k - tan_b), r * cot_k, r * (cot_k + tan_b)


def stage_from_depth(depth_m: float, geometry: DrillGeometry, beta_rad: float) -> int:
    """Li's engagement stage from the tip depth below the local surface.

    0: no contact. 1: lips partly engaged, outer corner still out (the uphill lip loads first).
    2: corner engaged over less than half a revolution. 3: over half or more. 4: fully engaged.
    """
    return stage_of(depth_m, stage_bounds(geometry, beta_rad))


@numba.njit(cache=True)
def stage_of(depth_m: float, bounds: tuple[float, float, float, float]) -> int:  # pragma: no cover (compiled)
    """Stage from precomputed :func:`stage_bounds` (compiled: the tip balance's kernel calls it per sample)."""
    touch, corner_in, half, full = bounds
    if depth_m <= touch:
        return 0
    if depth_m <= corner_in:
        return 1
    if depth_m < half:
        return 2
    if depth_m < full:
        return 3
    return 4


def _depth_grid(geometry: DrillGeometry, beta_rad: float, layer_depth_m: float, max_depth_m: float) -> np.ndarray:
    """Non-uniform depth grid: fine through the entry and through the layer boundary."""
    d_full = geometry.full_engagement_depth_m(beta_rad)
    d_touch = min(0.0, geometry.radius_m * (geometry.cot_kappa - math.tan(abs(beta_rad))))
    parts = [np.linspace(d_touch - 1e-6, d_full * 1.02, 240)]
    if layer_depth_m < max_depth_m:
        lo = layer_depth_m - d_full
        parts.append(np.linspace(lo, layer_depth_m + d_full * 1.02, 240))
    parts.append(np.linspace(d_touch, max_depth_m, 60))
    grid = np.unique(np.concatenate(parts))
    return grid[(grid >= d_touch - 1e-6) & (grid <= max_depth_m)]


@dataclass
class EngagementTable:
    """Cycle-averaged force tables over tip depth for one (drill, β, bone) scenario.

    ``edge[i]`` and ``per_chip[i]`` hold ``(F_x, F_y, F_z, M_z)`` at ``depth_m[i]``: forces (N) and the
    drilling torque about the axis (N·m) on the tool, tool frame; ``per_chip`` is per metre of chip.
    """

    depth_m: np.ndarray
    edge: np.ndarray
    per_chip: np.ndarray
    engaged_fraction: np.ndarray
    """Share of the lips' length in bone, averaged over a revolution, in [0, 1]."""

    @classmethod
    def build(
        cls,
        geometry: DrillGeometry,
        bone: BonePreset,
        beta_rad: float,
        cortical_thickness_m: float,
        max_depth_m: float,
    ) -> EngagementTable:
        """Integrate the element forces over the engaged lips for every depth of the grid."""
        lips = lip_geometry(geometry, beta_rad, cortical_thickness_m, max_depth_m)
        weight = geometry.n_lips / N_ANGULAR
        thrust = np.array([0.0, 0.0, -1.0])
        edge_tab = np.zeros((lips.depth_m.size, 4))
        chip_tab = np.zeros((lips.depth_m.size, 4))
        for part, mat in zip(lips.materials, (bone.cortical, bone.cancellous), strict=True):
            cut = part.cut
            for tab, kt, kf, kr, kch in (
                (edge_tab, mat.k_te_n_m, mat.k_fe_n_m, mat.k_re_n_m, mat.k_chisel_n_m),
                (chip_tab, mat.k_tc_pa, mat.k_fc_pa, mat.k_rc_pa, 0.0),
            ):
                f = kt * part.along_t + kr * part.along_r
                f = f + thrust * (kf * part.lip_len + kch * part.chisel_len)[:, None]
                tab[cut, :3] += weight * f
                tab[cut, 3] += weight * (-kt * part.lip_moment)  # torque opposes the +z spin
        return cls(depth_m=lips.depth_m, edge=edge_tab, per_chip=chip_tab, engaged_fraction=lips.engaged_fraction)


@dataclass(frozen=True)
class EngagedLips:
    """One material's engaged lips at the depths that cut it (tool frame, per revolution of one lip's angles).

    Attributes:
        cut: the grid's indices of the depths at which some element is in this material.
        along_t: ``Σ_φ l(φ) t(φ)``: engaged lip length times the unit tangential direction, summed (m), (C, 3).
        along_r: the same with the unit radial direction (m), (C, 3).
        lip_len: engaged lip length over all angles (m), (C,).
        lip_moment: its first moment about the axis (m²), (C,).
        chisel_len: engaged chisel-edge length over all angles (m), (C,).
    """

    cut: np.ndarray
    along_t: np.ndarray
    along_r: np.ndarray
    lip_len: np.ndarray
    lip_moment: np.ndarray
    chisel_len: np.ndarray


@dataclass(frozen=True)
class LipGeometry:
    """What the force tables need of the geometry alone: the bone's coefficients then only scale and add it."""

    depth_m: np.ndarray
    engaged_fraction: np.ndarray
    materials: tuple[EngagedLips, EngagedLips]
    """Cortical, cancellous."""


@functools.lru_cache(maxsize=64)
def lip_geometry(
    geometry: DrillGeometry, beta_rad: float, cortical_thickness_m: float, max_depth_m: float
) -> LipGeometry:
    """The engaged lips of every depth of the grid, for any bone.

    Cached: the env's force table and a controller's model of the same hole share it.
    """
    layer_depth = cortical_thickness_m / math.cos(beta_rad)  # cortical thickness along the axis
    grid = _depth_grid(geometry, beta_rad, layer_depth, max_depth_m)
    big_r, w = geometry.radius_m, geometry.web_radius_m
    edges = np.linspace(0.0, big_r, N_RADIAL + 1)
    r = 0.5 * (edges[1:] + edges[:-1])
    db = np.diff(edges) / math.sin(geometry.kappa_rad)
    phi = (np.arange(N_ANGULAR) + 0.5) * 2.0 * math.pi / N_ANGULAR
    cos_p, sin_p = np.cos(phi), np.sin(phi)
    setback = r[:, None] * (geometry.cot_kappa - cos_p[None, :] * math.tan(beta_rad))  # (R, Φ)
    is_lip = r >= w
    # Unit element force directions per φ for each coefficient family.
    tangential = np.stack([sin_p, -cos_p, np.zeros_like(phi)])  # opposes velocity (-sin, cos)
    radial = np.stack([-cos_p, -sin_p, np.zeros_like(phi)])  # toward the axis
    lip_total = float((is_lip * db).sum()) * N_ANGULAR
    sums = lip_sums(grid, setback, layer_depth, is_lip, db, r)
    lip_engaged, lip_phi, lip_len, lip_moment, chisel_len, cuts, same = sums
    materials = []
    for m in range(2):
        cut = np.flatnonzero(cuts[m])
        along_t = np.empty((cut.size, 3))
        along_r = np.empty((cut.size, 3))
        last = -2
        for n, j in enumerate(cut.tolist()):  # per depth: a BLAS product rounds by the shapes it is given
            if j == last + 1 and same[m, j]:  # the previous depth's row: the same product of the same numbers
                along_t[n], along_r[n] = along_t[n - 1], along_r[n - 1]
            else:
                along_t[n] = tangential @ lip_phi[m, j]
                along_r[n] = radial @ lip_phi[m, j]
            last = j
        materials.append(EngagedLips(cut, along_t, along_r, lip_len[m, cut], lip_moment[m, cut], chisel_len[m, cut]))
    fraction = lip_engaged / lip_total
    for a in (grid, fraction, *(a for part in materials for a in vars(part).values())):
        a.flags.writeable = False  # shared by every table of this geometry
    return LipGeometry(grid, fraction, (materials[0], materials[1]))


class ForceModel:
    """Cutting wrench on the tool at a given depth and chip thickness (tool frame, at the tip).

    A stateless run-time view over an :class:`EngagementTable`; contact (whether the tip is pressed
    against the bottom of the hole) is decided by the caller.
    """

    def __init__(self, table: EngagementTable) -> None:
        self.table = table
        self._grid_list = table.depth_m.tolist()

    def wrench(self, depth_m: float, chip_m: float) -> tuple[np.ndarray, float]:
        """Force (N, tool frame) and torque about the axis (N·m) when cutting at tip depth ``depth_m``."""
        grid = self._grid_list
        tab = self.table
        if depth_m <= grid[0]:
            row = tab.edge[0] + chip_m * tab.per_chip[0]
        elif depth_m >= grid[-1]:
            row = tab.edge[-1] + chip_m * tab.per_chip[-1]
        else:
            j = bisect.bisect_right(grid, depth_m)
            t = (depth_m - grid[j - 1]) / (grid[j] - grid[j - 1])
            lo = tab.edge[j - 1] + chip_m * tab.per_chip[j - 1]
            hi = tab.edge[j] + chip_m * tab.per_chip[j]
            row = lo + t * (hi - lo)
        return row[:3], float(row[3])
