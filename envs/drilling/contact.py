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

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drillgym.envs.drilling.contact_kernel import ROW_SIZE, run_samples
from drillgym.envs.drilling.force_model import EngagementTable, stage_bounds
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.drilling.hole import Hole
from drillgym.envs.read_through import ReadThrough

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


class TipContactSolver(ReadThrough):
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
        self.geometry = geometry
        self.skid_relief = skid_relief
        self.grid = np.ascontiguousarray(table.depth_m, dtype=float)
        self.set_surface(table, beta_rad)
        self.hole = hole
        self.k_lat_n = lateral_cut_resistance_n
        self.guidance_exponent = guidance_exponent
        if not 0.0 < wall_guidance_floor <= 1.0 or not wall_length_m > 0.0:
            raise ValueError(
                f"wall_guidance_floor={wall_guidance_floor} must be in (0, 1] and wall_length_m={wall_length_m} > 0"
            )
        self.wall_floor = wall_guidance_floor
        self.wall_length_m = wall_length_m
        self._key: tuple[float, float] = (math.nan, math.nan)
        self.force_scale = 1.0
        """Per-specimen multiplier on every cutting force (bone variability), set before an episode."""
        self.clear_effects()
        self.reset((0.0, 0.0, -3e-3))

    def set_surface(self, table: EngagementTable, beta_rad: float) -> None:
        """The bone surface's inclination β (rad) and its force table (built for that β, on the same depth grid).

        Sets the slope the tip's local depth reads (``tan β`` times the skid relief) and the stage bounds; the tip
        state is left where it is (:meth:`reset` or the caller recomputes ``depth_local``).
        """
        if table.depth_m.shape != self.grid.shape:
            raise ValueError(f"table grid has shape {table.depth_m.shape}; the solver's has {self.grid.shape}")
        self.table = table
        self.beta_rad = beta_rad
        self.tan_beta = self.skid_relief * math.tan(beta_rad)
        self.grid = np.ascontiguousarray(table.depth_m, dtype=float)
        self._bounds = stage_bounds(self.geometry, beta_rad)
        self._key = (math.nan, math.nan)

    def clear_effects(self) -> None:
        """No depth profile, nominal side guidance (see :meth:`set_depth_profile`, ``entry_guidance``, ``guidance_hook``)."""
        self.depth_profile: np.ndarray | None = None
        self.entry_guidance = 0.0
        """Extra side guidance while the lips enter, ``μ (1 − s)`` of the engaged share s < 1 (skid friction, -)."""
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
            self._rows = np.ascontiguousarray(rows, dtype=float)
        self._c = np.ascontiguousarray(compliance_m_n, dtype=float)
        share = float(np.interp(self.depth_local, self.table.depth_m, self.table.engaged_fraction))
        self._g = share**self.guidance_exponent * self._wall_factor()
        if self.entry_guidance != 0.0 and share < 1.0:
            self._g = self._g + self.entry_guidance * (1.0 - share)
        if self.guidance_hook is not None:
            self._g = self.guidance_hook(share, self._g)
        self._k_cut = self.k_lat_n / max(advance_per_update_m, 1e-7)

    def _wall_factor(self) -> float:
        """Share of full guidance the hole's wall gives: the floor until the full diameter is in, 1 a wall later."""
        if self.wall_floor >= 1.0:
            return 1.0
        wall = min(max((self.depth_local - self._bounds[3]) / self.wall_length_m, 0.0), 1.0)
        return self.wall_floor + (1.0 - self.wall_floor) * wall

    # ------------------------------------------------------------------ per F/T sample
    def update(self, target: tuple[float, float, float], servo_gain: float) -> ContactSample:
        """Move the servo toward ``target`` (gain in (0, 1]) and solve the balance: :meth:`run` for one target."""
        (row,) = self.run([target], servo_gain)
        return ContactSample(*row)

    def run(self, targets: list[tuple[float, float, float]], servo_gain: float) -> list[SampleRow]:
        """Samples of consecutive targets (task frame, m), one balance per target, in one compiled pass.

        The loop is :func:`~drillgym.envs.drilling.contact_kernel.run_samples`; the hole is cut in place.
        Rows are ``(tip, rigid, force, torque_axis, depth_local, stage, cutting)``, the fields of
        :class:`ContactSample`.
        """
        if not targets:
            return []
        hole = self.hole
        state = np.array([*self.rigid, *self.tip, self.bottom_z, self.depth_local])
        rows = np.empty((len(targets), ROW_SIZE))
        touching, j = run_samples(
            np.array(targets, dtype=float),
            servo_gain,
            state,
            self.touching,
            self._j,
            self.tan_beta,
            self._bounds,
            self.grid,
            self._rows,
            self._c,
            self._k_cut * self._g,
            hole.centre_xy_m,
            hole.filled,
            hole.bins,
            hole.bin_m,
            rows,
        )
        st = state.tolist()
        self.rigid, self.tip, self.bottom_z, self.depth_local = st[0:3], st[3:6], st[6], st[7]
        self.touching, self._j = touching, j
        out = rows.tolist()
        self.force, self.torque = out[-1][6:9], out[-1][9]
        return [
            ((r[0], r[1], r[2]), (r[3], r[4], r[5]), (r[6], r[7], r[8]), r[9], r[10], int(r[11]), r[12] == 1.0)
            for r in out
        ]
