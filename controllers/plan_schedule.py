"""A plan-scheduled controller: the base controller's gains and entry schedule chosen from the plan.

A fixed classical schedule (``li2023_tuned``) is one compromise over every bone, angle, feed and drill: the
gain across the plane of inclination that straightens a hard buffalo cortex over-corrects a soft porcine
one, and the slow entry that helps a hard cortex costs a soft one deviation. A *schedule residual* keeps
the base controller exactly as it is and moves only its tuning, once per hole, as a function of the plan
(what the cell knows before drilling: angle, feed, stick-out, cortical thickness, the named bone's
hardness):

    field = base_field · 2^(span · a),   a = policy(plan) ∈ [-1, 1] per field

so ``a = 0`` is the base controller itself. This is gain scheduling whose map from plan to gains is learnt
(``drillgym.training.schedule_env``) instead of tabulated by hand. Nothing changes during the hole: the
base controller's own feedback does all the work inside it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.feed_schedule import EntryFeedSchedule
from drillgym.controllers.registry import CONTROLLERS, PRESETS, make_controller, parse_spec
from drillgym.controllers.residual import PLAN_HIGH, plan_features
from drillgym.envs.constants import FEED_OVERRIDE_LOG2_MAX
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan

SCHEDULE_SPANS: dict[str, float] = {"kp": 0.5, "y_gain": 0.4, "entry_feed_scale": 1.0, "entry_depth_mm": 1.0}
"""Default fields a schedule residual moves and the log2 span of each: ±1 multiplies the base's value by
2^(±span) (KP ×0.71–1.41, the y gain ×0.76–1.32, the entry feed and depth ×0.5–2)."""

SchedulePolicy = Callable[[np.ndarray], np.ndarray]
"""Normalised plan features (:func:`normalized_plan`) -> action in [-1, 1] per scheduled field."""


def base_fields(base: str) -> tuple[str, dict[str, float]]:
    """The base spec's controller name and the numeric value of each of its fields (preset and defaults filled in)."""
    name, overrides = parse_spec(base)
    if name in PRESETS:
        name, preset = parse_spec(PRESETS[name])
        overrides = {**preset, **overrides}
    if name not in CONTROLLERS:
        raise UserError(f"a schedule residual needs a classical base controller, got {base!r}")
    cfg = CONTROLLERS[name][1]()
    values: dict[str, float] = {}
    for f in [*dataclasses.fields(cfg), *dataclasses.fields(EntryFeedSchedule)]:
        default = getattr(cfg, f.name, getattr(EntryFeedSchedule(), f.name, None))
        if isinstance(default, int | float) and not isinstance(default, bool):
            values[f.name] = float(overrides.get(f.name, default))
    return name, values


@dataclass(frozen=True)
class ScheduleSpec:
    """Which fields of the base a schedule residual moves, and how far.

    Attributes:
        base: the base controller's spec (a classical controller or preset, e.g. ``"li2023_tuned"``).
        spans: field -> log2 span (±1 of the action multiplies the base's value by 2^(±span)).
        plan_support: ``(low, high)`` plan features (:func:`drillgym.controllers.residual.plan_support`); the
            plan is clamped to it and scaled to [-1, 1] across it.
    """

    base: str = "li2023_tuned"
    spans: Mapping[str, float] = dataclasses.field(default_factory=lambda: dict(SCHEDULE_SPANS))
    plan_support: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        name, values = self.base_name, self.base_values
        for field, span in self.spans.items():
            if field not in values:
                raise UserError(f"{name} has no numeric field {field!r} to schedule; fields: {sorted(values)}")
            if not (math.isfinite(span) and 0.0 < span <= 3.0):
                raise UserError(f"span of {field!r} = {span} must be in (0, 3] (log2 of the largest factor)")
            if values[field] <= 0.0:
                raise UserError(
                    f"{self.base}: {field} = {values[field]:g} cannot be scaled by a factor; give the base a positive "
                    f"value first (e.g. {name}:{field}=1)"
                )
        if not self.spans:
            raise UserError("a schedule residual needs at least one field to schedule")

    @functools.cached_property
    def _base(self) -> tuple[str, dict[str, float]]:
        return base_fields(self.base)

    @property
    def base_name(self) -> str:
        """The base's controller name (a preset resolved)."""
        return self._base[0]

    @property
    def base_values(self) -> dict[str, float]:
        """The base's numeric fields (:func:`base_fields`), read once."""
        return self._base[1]

    @property
    def fields(self) -> tuple[str, ...]:
        """The scheduled fields, in action order."""
        return tuple(self.spans)

    @property
    def dims(self) -> int:
        """Size of the action."""
        return len(self.spans)

    def values(self, action: np.ndarray) -> dict[str, float]:
        """The scheduled fields' values for ``action`` (clipped to [-1, 1]); the entry feed and depth kept in their ranges."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.shape != (self.dims,):
            raise UserError(f"schedule action must have shape ({self.dims},), got {np.shape(action)}")
        if not np.all(np.isfinite(a)):
            raise UserError(f"schedule action {a.tolist()} contains NaN or inf")
        a = np.clip(a, -1.0, 1.0)
        base = self.base_values
        out = {f: base[f] * 2.0 ** (self.spans[f] * float(x)) for f, x in zip(self.fields, a, strict=True)}
        if "entry_feed_scale" in out:
            out["entry_feed_scale"] = float(np.clip(out["entry_feed_scale"], 2.0**-FEED_OVERRIDE_LOG2_MAX, 1.0))
        if "entry_depth_mm" in out:
            out["entry_depth_mm"] = min(out["entry_depth_mm"], 20.0)
        return out

    def controller_spec(self, action: np.ndarray) -> str:
        """The base spec with the scheduled fields set for ``action`` (``a = 0``: the base's own values)."""
        name, given = parse_spec(self.base)
        fields = {**given, **{k: f"{v:.6g}" for k, v in self.values(action).items()}}
        return f"{name}:" + ",".join(f"{k}={v}" for k, v in fields.items())


def normalized_plan(plan: Any, support: tuple[np.ndarray, np.ndarray] | None) -> np.ndarray:
    """The plan's features clamped to ``support`` and scaled to [-1, 1] across it (0 where it is a point)."""
    low, high = (np.zeros_like(PLAN_HIGH), PLAN_HIGH) if support is None else support
    f = plan_features(plan, (low, high)).astype(np.float64)
    width = np.asarray(high, dtype=np.float64) - np.asarray(low, dtype=np.float64)
    mid = (np.asarray(high, dtype=np.float64) + np.asarray(low, dtype=np.float64)) / 2.0
    scaled = np.divide(2.0 * (f - mid), width, out=np.zeros_like(f), where=width > 0)
    return scaled.astype(np.float32)


class PlanScheduledController(Controller):
    """The base controller, tuned for each hole by a policy of the plan.

    Args:
        spec: the base and the scheduled fields.
        policy: normalised plan features -> action; None: the action is zero (the base controller).
        description: what :meth:`describe` reports under ``config`` (default: the spec).
    """

    name = "plan_schedule"

    def __init__(
        self, spec: ScheduleSpec, policy: SchedulePolicy | None = None, description: dict[str, Any] | None = None
    ) -> None:
        super().__init__()
        self.spec = spec
        self.policy = policy
        self._description = description
        self.action = np.zeros(spec.dims, dtype=np.float32)
        """The schedule action of the current hole."""
        self.inner: Controller = make_controller(spec.controller_spec(self.action))
        """The base controller with this hole's tuning."""
        self.batchable = self.inner.batchable  # a batch shares one plan, so one tuning

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Choose this hole's tuning from the plan and build the tuned base controller."""
        obs = normalized_plan(plan, self.spec.plan_support)
        action = np.zeros(self.spec.dims) if self.policy is None else self.policy(obs)
        self.action = np.clip(np.asarray(action, dtype=np.float32).reshape(-1), -1.0, 1.0)
        self.inner = make_controller(self.spec.controller_spec(self.action))
        self.inner.set_plan(plan, num_episodes)
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """Reset the tuned base controller."""
        self.inner.reset()

    def stack_part(self) -> Controller:
        """The tuned base controller: holes tuned differently step together as their bases."""
        return self.inner.stack_part()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The tuned base controller's action."""
        return self.inner.act(obs)

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """The tuned base controller's actions (every episode of the batch drills the same plan)."""
        return self.inner.act_batch(obs)

    def describe(self) -> dict[str, Any]:
        """Name and configuration: the spec, and this hole's tuned fields."""
        if self._description is not None:
            return {"name": self.name, "config": self._description}
        cfg = {"base": self.spec.base, "spans": dict(self.spec.spans), "values": self.spec.values(self.action)}
        return {"name": self.name, "config": cfg}
