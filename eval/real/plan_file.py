"""A multi-hole plan for ``drillgym run --plan FILE``: one entry point per hole, checked before anything moves.

The file is YAML, or JSON when its name ends in ``.json``::

    scenario:                     # optional: every hole's plan, the env's arguments as --scenario takes them
      feed_mm_s: 0.5
      depth_mm: 6
    holes:                        # drilled in this order
      - name: A1                  # optional (default hole1, hole2, ...): names the hole's log
        entry_point_base_mm: [-450.0, -110.0, 100.0]
      - name: A2
        entry_point_base_mm: [-450.0, -104.0, 100.0]
        scenario: {depth_mm: 5}   # optional: this hole's changes to the plan above
        seed: 7                   # optional (default: --seed plus the hole's position minus 1)

An entry point is the registered point on the bone surface where the hole starts, in the UR base frame (mm; the
same point as ``CellParams.entry_point_base_m``, which is in m). Every hole is drilled along the cell's drill axis
(:data:`drillgym.envs.cell_params.R_BASE_TASK`: −z of the base). Refused, naming the file and the hole: a missing
or unknown key, a value of the wrong type, a NaN or infinite number, a scenario value out of its range
(:class:`drillgym.envs.scenario.Scenario`), an entry point outside :data:`ENTRY_RADIUS_MM` of the base origin, a
name used twice, and two holes that would drill the same entry point: drill axes closer than
:func:`same_entry_tolerance_m`.
"""

from __future__ import annotations

import itertools
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs.cell_params import R_BASE_TASK
from drillgym.envs.errors import UserError, read_json, read_yaml
from drillgym.envs.scenario import Scenario

PLAN_KEYS = ("scenario", "holes")
HOLE_KEYS = ("name", "entry_point_base_mm", "scenario", "seed")
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]{0,39}\Z")
"""A hole's name: it names its log file, so letters, digits, ``_``, ``.``, ``-`` (40 at most)."""
ENTRY_RADIUS_MM = (100.0, 850.0)
"""Distance of an entry point from the base origin (mm): beyond 850 mm (the UR5's reach) the robot cannot get
there; within 100 mm the point is inside the robot's base (an entry point written in m instead of mm, most likely)."""
DRILL_AXIS_BASE = R_BASE_TASK[:, 2]
"""The drill axis (unit vector, base frame) of every hole: into the bone."""


@dataclass(frozen=True)
class PlannedHole:
    """One hole of a plan: where (entry point, m, UR base frame), what (the scenario), its reset seed."""

    index: int
    """Its position in the plan, from 1."""
    name: str
    entry_base_m: tuple[float, float, float]
    scenario: Scenario
    seed: int

    @property
    def label(self) -> str:
        """``hole 2 (A2)``: its position and name, as the console and the errors say it."""
        return f"hole {self.index} ({self.name})"

    @property
    def entry_base_mm(self) -> list[float]:
        """The entry point in mm (UR base frame), as the plan file gives it."""
        return [round(v * 1e3, 6) for v in self.entry_base_m]

    def describe(self) -> str:
        """Where and what, for the console: entry point (mm, base frame), depth, feed, angle, drill, seed."""
        x, y, z = self.entry_base_mm
        sc = self.scenario
        return (
            f"entry point ({x:.1f}, {y:.1f}, {z:.1f}) mm (UR base frame), {sc.depth_mm:g} mm deep at "
            f"{sc.feed_mm_s:g} mm/s, beta {sc.beta_deg:g} deg, {sc.drill_diameter_mm:g} mm drill, seed {self.seed}"
        )

    def to_json(self) -> dict[str, Any]:
        """What the record keeps of it (``plan.json``)."""
        return {
            "hole": self.index,
            "name": self.name,
            "entry_point_base_mm": self.entry_base_mm,
            "scenario": self.scenario.to_dict(),
            "seed": self.seed,
        }


@dataclass(frozen=True)
class DrillingPlan:
    """The holes of a plan file, in the order they are drilled."""

    path: Path
    holes: tuple[PlannedHole, ...]

    def to_json(self) -> dict[str, Any]:
        """What the record keeps of it (``plan.json``)."""
        return {"plan_file": str(self.path), "holes": [h.to_json() for h in self.holes]}


def axis_distance_m(a_base_m: Sequence[float], b_base_m: Sequence[float]) -> float:
    """Distance between the drill axes through two entry points (m): their offset across :data:`DRILL_AXIS_BASE`."""
    d = np.asarray(b_base_m, dtype=float) - np.asarray(a_base_m, dtype=float)
    return float(np.linalg.norm(d - (d @ DRILL_AXIS_BASE) * DRILL_AXIS_BASE))


def same_entry_tolerance_m(a: PlannedHole, b: PlannedHole) -> float:
    """Two holes drill the same entry point when their drill axes are closer than this (m).

    The mean of their drill diameters: closer, their bores cut into each other (with one drill: its diameter).
    """
    return 0.5 * (a.scenario.drill_diameter_m + b.scenario.drill_diameter_m)


def far_transits(holes: Sequence[PlannedHole], max_m: float) -> list[tuple[PlannedHole, PlannedHole, float]]:
    """Consecutive holes whose entry points are more than ``max_m`` apart (m): ``(from, to, distance_m)``."""
    out = []
    for a, b in itertools.pairwise(holes):
        d = float(np.linalg.norm(np.subtract(b.entry_base_m, a.entry_base_m)))
        if d > max_m:
            out.append((a, b, d))
    return out


def load_plan(path: Path, first_seed: int = 0) -> DrillingPlan:
    """Read and check a plan file (see the module docstring); ``ValueError`` naming the file and the hole."""
    path = Path(path)
    data = _read(path)
    if not isinstance(data, Mapping):
        raise UserError(f"{path}: a plan is a mapping with a 'holes' list; got {type(data).__name__}")
    _known_keys(data, PLAN_KEYS, f"{path}")
    if "holes" not in data:
        raise UserError(f"{path}: missing key 'holes' (a list of holes, each with entry_point_base_mm)")
    common = _scenario_mapping(data.get("scenario", {}), f"{path}: scenario")
    raw_holes = data["holes"]
    if not isinstance(raw_holes, list) or not raw_holes:
        raise UserError(f"{path}: 'holes' must be a non-empty list of holes; got {raw_holes!r}")
    holes = tuple(_hole(path, k, raw, common, first_seed) for k, raw in enumerate(raw_holes, start=1))
    _check_names(path, holes)
    _check_entries_once(path, holes)
    return DrillingPlan(path, holes)


def _read(path: Path) -> Any:
    suffix = path.suffix.lower()
    if suffix == ".json":
        return read_json(path)  # OSError names the file
    if suffix not in (".yaml", ".yml"):
        raise UserError(f"{path}: a plan file is YAML (.yaml, .yml) or JSON (.json)")
    return read_yaml(path)


def _known_keys(data: Mapping[Any, Any], known: Sequence[str], where: str) -> None:
    unknown = sorted(str(k) for k in data if k not in known)
    if unknown:
        raise UserError(f"{where}: unknown key(s) {unknown}; expected {list(known)}")


def _scenario_mapping(raw: Any, where: str) -> dict[str, Any]:
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise UserError(f"{where} must be a mapping of the env's arguments (e.g. {{feed_mm_s: 0.5}}); got {raw!r}")
    if "tracker" in raw:
        raise UserError(f"{where}: 'tracker' is not a plan value: drillgym run --tracker names the tracker")
    return {str(k): v for k, v in raw.items()}


def _hole(path: Path, index: int, raw: Any, common: dict[str, Any], first_seed: int) -> PlannedHole:
    where = f"{path}: hole {index}"
    if not isinstance(raw, Mapping):
        raise UserError(f"{where}: a hole is a mapping with entry_point_base_mm; got {raw!r}")
    name = raw.get("name", f"hole{index}")
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise UserError(f"{where}: name {name!r} must be 1-40 letters, digits, '_', '.' or '-' (it names the log)")
    where = f"{path}: hole {index} ({name})"
    _known_keys(raw, HOLE_KEYS, where)
    if "entry_point_base_mm" not in raw:
        raise UserError(f"{where}: missing key 'entry_point_base_mm' (x, y, z of the entry point, mm, UR base frame)")
    entry_m = _entry_point_m(raw["entry_point_base_mm"], where)
    changes = _scenario_mapping(raw.get("scenario", {}), f"{where}: scenario")
    try:
        scenario = Scenario.from_kwargs(**{**common, **changes})
    except (TypeError, ValueError) as e:
        raise UserError(f"{where}: scenario: {e}") from e
    seed = raw.get("seed", first_seed + index - 1)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise UserError(f"{where}: seed {seed!r} must be a whole number >= 0")
    return PlannedHole(index, name, entry_m, scenario, seed)


def _entry_point_m(raw: Any, where: str) -> tuple[float, float, float]:
    what = f"{where}: entry_point_base_mm"
    numbers = isinstance(raw, list) and all(isinstance(v, int | float) and not isinstance(v, bool) for v in raw)
    if not numbers or len(raw) != 3:
        raise UserError(f"{what} must be [x, y, z] in mm (UR base frame); got {raw!r}")
    if not all(math.isfinite(v) for v in raw):
        raise UserError(f"{what} {raw!r} must be finite numbers (no NaN or infinity)")
    radius_mm = math.dist(raw, (0.0, 0.0, 0.0))
    lo, hi = ENTRY_RADIUS_MM
    if radius_mm < lo:
        raise UserError(
            f"{what} {raw!r} is {radius_mm:.3g} mm from the base origin, inside the robot's base (< {lo:g} mm): "
            "entry points are in mm, not m"
        )
    if radius_mm > hi:
        raise UserError(
            f"{what} {raw!r} is {radius_mm:.0f} mm from the base origin, beyond the UR5's reach ({hi:g} mm)"
        )
    return (raw[0] * 1e-3, raw[1] * 1e-3, raw[2] * 1e-3)


def _check_names(path: Path, holes: Sequence[PlannedHole]) -> None:
    seen: dict[str, PlannedHole] = {}
    for hole in holes:
        if hole.name in seen:
            raise UserError(f"{path}: holes {seen[hole.name].index} and {hole.index} are both named {hole.name!r}")
        seen[hole.name] = hole


def _check_entries_once(path: Path, holes: Sequence[PlannedHole]) -> None:
    """Refuse two holes on the same entry point: drill axes closer than :func:`same_entry_tolerance_m`."""
    for i, a in enumerate(holes):
        for b in holes[i + 1 :]:
            distance_m, tolerance_m = axis_distance_m(a.entry_base_m, b.entry_base_m), same_entry_tolerance_m(a, b)
            if distance_m < tolerance_m:
                raise UserError(
                    f"{path}: {a.label} and {b.label} drill the same entry point: their drill axes are "
                    f"{distance_m * 1e3:.2f} mm apart, closer than the drill diameter ({tolerance_m * 1e3:.2f} mm), "
                    "so the second would cut into the first's hole; each entry point is drilled once"
                )
