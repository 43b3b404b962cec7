"""A residual controller: a base controller plus a learnt correction, written once.

``action = clip(base(obs) + scale · residual)`` (``add``), or the base's correction across the drill times
``1 + scale · residual`` (``gain``). :class:`ResidualController` owns the base controller (its filters, PID
memory and path prediction), builds the policy's observation (the cell's observation plus the base's
action, the policy's previous residual and the plan) and combines the residual with the base's action.
Training (``drillgym.training.ResidualWrapper``, where the RL agent supplies the residual) and deployment
(``make_controller("residual:PATH")``, where a saved policy does) both run through it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.envs.drilling.bone import nominal_hardness
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan

BASE_ACTION_KEY = "base_action"
PLAN_KEY = "plan"
"""Planned interaction angle (rad), feed (m/s), drill stick-out (m), cortical thickness (m) and the named
bone type's nominal hardness (-): what the cell knows before drilling (the plan from imaging, the
specimen the surgeon names and the tool measured on the bench)."""
PREV_RESIDUAL_KEY = "residual_prev"
"""The policy's own previous residual (zero at an episode start): the controller knows what it sent, and
with it a memoryless policy can hold or integrate a correction."""

RESIDUAL_AXES = ("lateral", "xyz")
FEED_CEILINGS = ("base", "nominal")
"""How fast a feed residual may drill: ``base``: never faster than the base controller (it can only slow
it); ``nominal``: never faster than the plan's feed or the base, whichever is faster (over a base that
slows the feed, it may undo that slowing, up to the plan's feed)."""
RESIDUAL_MODES = ("add", "gain")
"""``add``: the residual adds a correction (± ``scale`` of the action range); ``gain``: it scales the base's
own correction by ``1 + scale · residual`` per axis (it can strengthen, weaken or cancel what the base
does, never add a correction where the base has none)."""

PLAN_HIGH = np.array([np.pi / 2, 5e-3, 0.1, 0.05, 3.0], dtype=np.float32)
"""Upper bounds of the plan features (their lower bounds are 0)."""

ResidualPolicy = Callable[[dict[str, np.ndarray]], np.ndarray]
"""The policy's observation (:meth:`ResidualController.observe`) -> residual in [-1, 1]."""


def check_mode(mode: str, feed_ceiling: str = "base") -> None:
    """Raise ``ValueError`` unless ``mode`` is one of :data:`RESIDUAL_MODES` and ``feed_ceiling`` of :data:`FEED_CEILINGS`."""
    if mode not in RESIDUAL_MODES:
        raise UserError(f"residual mode {mode!r}; choose from {RESIDUAL_MODES}")
    if feed_ceiling not in FEED_CEILINGS:
        raise UserError(f"residual feed ceiling {feed_ceiling!r}; choose from {FEED_CEILINGS}")


def plan_features(plan: Any, support: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """``[beta_rad, feed_m_s, stickout_m, cortical_thickness_m, bone_hardness]`` of a :class:`drillgym.envs.plan.DrillPlan`.

    ``bone_hardness`` is the planned bone type's nominal cortical hardness relative to buffalo cortex
    (:func:`drillgym.envs.drilling.bone.nominal_hardness`): the surgeon names the specimen, not its true hardness.
    With ``support`` (:func:`plan_support`) the features are clamped to it instead of to their full bounds.
    """
    values = [plan.beta_rad, plan.feed_m_s, plan.stickout_m, plan.cortical_thickness_m, nominal_hardness(plan.bone)]
    low, high = (0.0, PLAN_HIGH) if support is None else support
    return np.clip(np.array(values, dtype=np.float32), low, high).astype(np.float32)


_PLAN_RANGE_KEYS = (
    ("beta_deg", np.pi / 180.0),
    ("feed_mm_s", 1e-3),
    ("stickout_mm", 1e-3),
    ("cortical_thickness_mm", 1e-3),
)
"""Training-range name and its factor to the plan feature's SI unit, in feature order."""


def plan_support(ranges: Mapping[str, tuple[float, float]], bones: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """Lowest and highest plan features of a policy trained inside ``ranges`` (user units) on ``bones``.

    A feature whose range is not given keeps its full bounds (0 to :data:`PLAN_HIGH`).
    """
    low = np.zeros(PLAN_HIGH.shape, dtype=np.float32)
    high = PLAN_HIGH.copy()
    for i, (name, to_si) in enumerate(_PLAN_RANGE_KEYS):
        if name in ranges:
            low[i], high[i] = (np.float32(v * to_si) for v in ranges[name])
    hardness = [nominal_hardness(b) for b in bones]
    low[-1], high[-1] = min(hardness), max(hardness)
    return low, high


def augment(
    obs: Mapping[str, np.ndarray],
    base_action: np.ndarray,
    prev_residual: np.ndarray | None = None,
    plan: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """The residual policy's observation.

    The cell's observation plus the base's action and, if given, the policy's previous residual and the
    plan features.
    """
    out = {**obs, BASE_ACTION_KEY: base_action}
    if prev_residual is not None:
        out[PREV_RESIDUAL_KEY] = prev_residual
    if plan is not None:
        out[PLAN_KEY] = plan
    return out


def residual_dims(residual_feed: bool, axes: str = "lateral") -> int:
    """Size of the residual: 2 lateral axes (across the drill) or 3 base axes, plus the feed if enabled."""
    if axes not in RESIDUAL_AXES:
        raise UserError(f"residual axes={axes!r}; choose from {RESIDUAL_AXES}")
    return (2 if axes == "lateral" else 3) + (1 if residual_feed else 0)


def combine(
    base_action: np.ndarray,
    residual: np.ndarray,
    scale: float,
    R_base_task: np.ndarray | None = None,
    mode: str = "add",
    feed_ceiling: str = "base",
) -> np.ndarray:
    """``clip(base + scale · residual)`` (mode ``add``) or ``clip(base · (1 + scale · residual))`` (``gain``).

    With ``R_base_task`` the first two residual entries are task x and y (across the drill) and are
    turned into base axes; without it the first three are base x, y, z. A last extra entry, if any,
    is the feed residual. With ``feed_ceiling="base"`` only its negative part is added, so it can slow the
    base's feed (down to 2^(-2 · scale) of it) but never drill faster than the base; with ``"nominal"`` it is
    added whole (× 2^(±2 · scale)) and the sum capped at the plan's feed or the base's, whichever is faster.
    Without it the feed is the base's.
    """
    out = np.asarray(base_action, dtype=np.float64).copy()
    r = np.clip(np.asarray(residual, dtype=np.float64).reshape(-1), -1.0, 1.0)
    n_xyz = 2 if R_base_task is not None else 3
    check_mode(mode, feed_ceiling)
    if R_base_task is not None:
        lateral = np.asarray(R_base_task)[:, :2]
        step = r[:2] * (lateral.T @ out[:3]) if mode == "gain" else r[:2]
        out[:3] += scale * (lateral @ step)
    else:
        out[:3] += scale * (r[:3] * out[:3] if mode == "gain" else r[:3])
    if r.size > n_xyz and feed_ceiling == "nominal":
        out[3] = min(out[3] + scale * r[n_xyz], max(out[3], 0.0))
    elif r.size > n_xyz:
        out[3] += scale * min(r[n_xyz], 0.0)
    return np.clip(out, -1.0, 1.0).astype(np.float32)


@dataclass(frozen=True)
class ResidualSpec:
    """How a residual acts on its base and what its policy observes.

    Attributes:
        scale: residual ±1 maps to ± ``scale`` of the env's action range (``add``; 0.5: ±1 mm), or to a gain
            of ``1 ± scale`` on the base's correction (``gain``).
        mode: :data:`RESIDUAL_MODES`.
        axes: ``"lateral"``: the residual moves the tip across the drill only (task x, y), as the
            compensators do; ``"xyz"``: along the three base axes (it can then plunge the drill).
        residual_feed: the residual may also change the base's feed (:data:`FEED_CEILINGS`).
        feed_ceiling: how fast the feed residual may drill.
        observe_prev_residual: the policy observes its previous residual (``residual_prev``).
        observe_plan: the policy observes the plan's features (``plan``).
        plan_support: ``(low, high)`` plan features (:func:`plan_support`): the plan the policy sees is
            clamped to them, so that outside its training ranges it acts as at their nearest edge instead
            of extrapolating (None: clamped to :data:`PLAN_HIGH` only).
    """

    scale: float = 0.5
    mode: str = "add"
    axes: str = "lateral"
    residual_feed: bool = False
    feed_ceiling: str = "base"
    observe_prev_residual: bool = False
    observe_plan: bool = False
    plan_support: tuple[np.ndarray, np.ndarray] | None = None

    def __post_init__(self) -> None:
        check_mode(self.mode, self.feed_ceiling)
        residual_dims(self.residual_feed, self.axes)
        if not 0.0 < self.scale <= 2.0:
            raise UserError(f"scale={self.scale} must be in (0, 2]")

    @property
    def dims(self) -> int:
        """Size of the residual action."""
        return residual_dims(self.residual_feed, self.axes)


class ResidualController(Controller):
    """A base controller plus a residual: ``observe`` builds the policy's input, ``compose`` the action.

    Args:
        base: the base controller (its state lives here and is reset with each episode).
        spec: how the residual acts and what the policy observes.
        policy: the policy's observation -> residual; None where the residual comes from outside (an RL
            agent acting through ``drillgym.training.ResidualWrapper``), in which case :meth:`act` is not
            available.
        description: what :meth:`describe` reports under ``config`` (default: the spec and the base's).
    """

    name = "residual"

    def __init__(
        self,
        base: Controller,
        spec: ResidualSpec,
        policy: ResidualPolicy | None = None,
        description: dict[str, Any] | None = None,
    ) -> None:
        super().__init__()
        self.base = base
        self.spec = spec
        self.policy = policy
        self._description = description
        self.base_action = np.zeros(4, dtype=np.float32)
        self._plan_features = np.zeros(PLAN_HIGH.shape, dtype=np.float32)
        self._R: np.ndarray | None = None
        self.reset()

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Hand the plan to the base controller too; resets both."""
        self.base.set_plan(plan)
        self._plan_features = plan_features(plan, self.spec.plan_support)
        self._R = plan.R_base_task if self.spec.axes == "lateral" else None
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """Mark an episode start: the base controller resets on its next call, the previous residual is 0."""
        self._start = True
        self._prev_residual = np.zeros(self.spec.dims, dtype=np.float32)

    def observe(self, obs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Run the base controller on ``obs``; the policy's observation (the base's action is kept for :meth:`compose`)."""
        if self.spec.observe_plan and self.plan is None:
            raise RuntimeError("this residual policy observes the plan: call set_plan(plan) first")
        self.base_action, _ = self.base.predict(dict(obs), episode_start=np.array([self._start]))
        self._start = False
        return augment(
            obs,
            self.base_action.copy(),
            self._prev_residual.copy() if self.spec.observe_prev_residual else None,
            self._plan_features.copy() if self.spec.observe_plan else None,
        )

    def compose(self, residual: np.ndarray) -> np.ndarray:
        """The action for the last observed step: the base's action with ``residual`` (clipped to [-1, 1])."""
        r = np.asarray(residual, dtype=np.float64).reshape(-1)
        if r.shape != (self.spec.dims,):
            raise UserError(f"residual action must have shape ({self.spec.dims},), got {np.shape(residual)}")
        if not np.all(np.isfinite(r)):
            raise UserError(f"residual action {r.tolist()} contains NaN or inf")
        s = self.spec
        action = combine(self.base_action, r, s.scale, self._R, s.mode, s.feed_ceiling)
        self._prev_residual = np.clip(r, -1.0, 1.0).astype(np.float32)
        return action

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Base action plus the policy's residual."""
        if self.policy is None:
            raise RuntimeError("this residual controller has no policy: its residual comes from outside (compose)")
        return self.compose(self.policy(self.observe(obs)))

    def describe(self) -> dict[str, Any]:
        """Name and configuration (the given description, or the spec and the base's)."""
        if self._description is not None:
            return {"name": self.name, "config": self._description}
        s = self.spec
        cfg = {k: getattr(s, k) for k in ("scale", "mode", "axes", "residual_feed", "feed_ceiling")}
        return {"name": self.name, "config": {**cfg, "base": self.base.describe()}}
