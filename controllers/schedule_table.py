"""A gain-scheduling table: the classical counterpart of the schedule residual.

The schedule residual (:mod:`drillgym.controllers.plan_schedule`) learns a map from the plan to the base
controller's tuning. A control engineer would tabulate it instead: tune the base at a few *anchor* plans and
interpolate between them. This module is that table; ``drillgym tune-table``
(:mod:`drillgym.eval.bench.tune_table`) fills it.

**Anchors.** The nominal plan (the paper scenario), then each plan feature moved alone to other values (the
ends of its training range; for the bone feature, the other training bones), the rest at nominal. Each anchor
holds a schedule action ``a ∈ [-1, 1]^k`` (``field = base_field · 2^(span · a)``, as the residual's).

**Interpolation** (separable, piecewise linear): ``a(x) = a_nominal + Σ_f d_f(x_f)``, where ``d_f`` interpolates
linearly over feature ``f``'s knots, through 0 at the nominal value and ``a_anchor − a_nominal`` at each
anchor that moves ``f`` (flat beyond the outermost knots); the sum is clipped to [-1, 1]. At every anchor the
table gives that anchor's action exactly. Features are the normalised plan (:func:`normalized_plan`:
clamped to the table's plan support, scaled to [-1, 1]).

A table is a JSON file (:data:`TABLE_FORMAT`); ``make_controller("table:PATH")`` (or ``table:shipped``, the
table shipped in ``controllers/tables/``) loads it as a
:class:`drillgym.controllers.plan_schedule.PlanScheduledController`.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec
from drillgym.envs.errors import UserError, read_json

TABLE_FORMAT = "drillgym-schedule-table/1"
"""``format`` of a table file."""
TABLE_DIR = Path(__file__).parent / "tables"
NAMED_TABLES = {"shipped": "schedule_table.json"}
"""``table:NAME`` -> file in :data:`TABLE_DIR`."""


@dataclass(frozen=True)
class Anchor:
    """One tuned plan of the table.

    Attributes:
        name: e.g. ``nominal``, ``beta_deg=15``, ``bone=porcine_femur``.
        scenario: the plan's scenario arguments (user units), beside the env's defaults.
        features: the normalised plan features (:func:`drillgym.controllers.plan_schedule.normalized_plan`).
        action: the tuned schedule action, one value per scheduled field, in [-1, 1].
    """

    name: str
    scenario: dict[str, Any]
    features: tuple[float, ...]
    action: tuple[float, ...]


@dataclass(frozen=True)
class ScheduleTable:
    """Anchors (the first is the nominal plan) and the schedule they tune.

    Attributes:
        spec: the base controller, the scheduled fields and spans, and the plan support.
        anchors: the nominal anchor first; every other anchor differs from it in one feature.
        meta: how the table was made (command, budget, seeds, objective), kept in the file.
    """

    spec: ScheduleSpec
    anchors: tuple[Anchor, ...]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.anchors:
            raise UserError("a schedule table needs at least the nominal anchor")
        dims, nf = self.spec.dims, len(self.anchors[0].features)
        for a in self.anchors:
            if len(a.action) != dims or len(a.features) != nf:
                raise UserError(
                    f"anchor {a.name!r}: {len(a.action)} actions for {dims} fields, {len(a.features)} features"
                )
            if not all(math.isfinite(v) and -1.0 <= v <= 1.0 for v in a.action):
                raise UserError(f"anchor {a.name!r}: actions {a.action} must be finite and in [-1, 1]")
            moved = [i for i, (x, x0) in enumerate(zip(a.features, self.anchors[0].features, strict=True)) if x != x0]
            if a is not self.anchors[0] and len(moved) != 1:
                raise UserError(
                    f"anchor {a.name!r} must differ from the nominal plan in exactly one feature, not {moved}"
                )

    def action(self, features: np.ndarray) -> np.ndarray:
        """The interpolated schedule action at normalised plan ``features``, in [-1, 1]."""
        x = np.asarray(features, dtype=np.float64).reshape(-1)
        nominal = self.anchors[0]
        x0, a0 = np.asarray(nominal.features), np.asarray(nominal.action)
        out = a0.copy()
        for f in range(len(x0)):
            knots = [(x0[f], np.zeros_like(a0))]
            knots += [(a.features[f], np.asarray(a.action) - a0) for a in self.anchors[1:] if a.features[f] != x0[f]]
            if len(knots) == 1:
                continue
            knots.sort(key=lambda k: k[0])
            xs = np.array([k[0] for k in knots])
            for j in range(len(a0)):
                out[j] += np.interp(x[f], xs, [k[1][j] for k in knots])
        return np.clip(out, -1.0, 1.0)

    def controller(self) -> PlanScheduledController:
        """The base controller tuned per hole by this table."""
        description = {"table": self.meta.get("path", ""), "base": self.spec.base, "anchors": len(self.anchors)}
        return PlanScheduledController(self.spec, lambda obs: self.action(obs).astype(np.float32), description)

    def to_dict(self) -> dict[str, Any]:
        """The table as JSON data (:data:`TABLE_FORMAT`)."""
        low, high = self.spec.plan_support or (None, None)
        return {
            "format": TABLE_FORMAT,
            "base": self.spec.base,
            "spans": dict(self.spec.spans),
            "plan_support": None if low is None else [np.asarray(low).tolist(), np.asarray(high).tolist()],
            "anchors": [
                {"name": a.name, "scenario": a.scenario, "features": list(a.features), "action": list(a.action)}
                for a in self.anchors
            ],
            "meta": {k: v for k, v in self.meta.items() if k != "path"},
        }

    def save(self, path: Path) -> None:
        """Write the table as JSON (a new file; an existing one is an error)."""
        if path.exists():
            raise FileExistsError(f"{path} exists; a table is never overwritten (choose another --out)")
        path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")


def table_from_dict(data: dict[str, Any], source: str = "table") -> ScheduleTable:
    """A table from its JSON data; a wrong format or field raises ``ValueError`` naming ``source``."""
    if not isinstance(data, dict) or data.get("format") != TABLE_FORMAT:
        raise UserError(f"{source}: not a schedule table (format {TABLE_FORMAT!r} expected)")
    try:
        support = data.get("plan_support")
        spec = ScheduleSpec(
            base=str(data["base"]),
            spans={str(k): float(v) for k, v in data["spans"].items()},
            plan_support=None
            if support is None
            else (np.asarray(support[0], dtype=np.float32), np.asarray(support[1], dtype=np.float32)),
        )
        anchors = tuple(
            Anchor(
                str(a["name"]),
                dict(a["scenario"]),
                tuple(float(v) for v in a["features"]),
                tuple(float(v) for v in a["action"]),
            )
            for a in data["anchors"]
        )
    except (KeyError, TypeError, IndexError) as e:
        raise UserError(f"{source}: malformed schedule table ({type(e).__name__}: {e})") from e
    return ScheduleTable(spec, anchors, {**dict(data.get("meta") or {}), "path": source})


def resolve_table(text: str) -> Path:
    """``shipped`` (or another name of :data:`NAMED_TABLES`) or a path -> the table file's path."""
    return TABLE_DIR / NAMED_TABLES[text] if text in NAMED_TABLES else Path(text)


def load_table(text: str) -> ScheduleTable:
    """Read a table file (a path or a name of :data:`NAMED_TABLES`); clear errors for a missing or bad file."""
    if not text:
        raise UserError("table controllers need a file: table:PATH/TO/table.json (or table:shipped)")
    path = resolve_table(text)
    try:
        data = read_json(path)
    except FileNotFoundError:
        raise FileNotFoundError(f"schedule table {path} not found (drillgym tune-table writes one)") from None
    return table_from_dict(data, str(path))


def load_table_controller(text: str) -> PlanScheduledController:
    """``table:PATH`` -> controller (registered for :func:`drillgym.controllers.make_controller`)."""
    return load_table(text).controller()
