"""Residual RL on top of a classical compensator: ``action = clip(base(obs) + scale · residual)``.

The wrapper owns the base controller (its filters, PID memory and path prediction live here and are
reset with the env), tells it the plan at every reset, and shows the policy the base's action as an
extra observation key, with the policy's previous residual. With a residual of zero the wrapped env behaves exactly as the base controller
does: the policy starts from the baseline.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.controllers import Controller, make_controller
from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.drilling.bone import nominal_hardness
from drillgym.training.domain_randomization import TRAINING_BONES

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


def check_mode(mode: str, feed_ceiling: str = "base") -> None:
    """Raise ``ValueError`` unless ``mode`` is one of :data:`RESIDUAL_MODES` and ``feed_ceiling`` of :data:`FEED_CEILINGS`."""
    if mode not in RESIDUAL_MODES:
        raise ValueError(f"residual mode {mode!r}; choose from {RESIDUAL_MODES}")
    if feed_ceiling not in FEED_CEILINGS:
        raise ValueError(f"residual feed ceiling {feed_ceiling!r}; choose from {FEED_CEILINGS}")


PLAN_HIGH = np.array([np.pi / 2, 5e-3, 0.1, 0.05, 3.0], dtype=np.float32)
"""Upper bounds of the plan features (their lower bounds are 0)."""


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


def plan_support(
    ranges: Mapping[str, tuple[float, float]], bones: Sequence[str] = TRAINING_BONES
) -> tuple[np.ndarray, np.ndarray]:
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
    """The residual policy's observation, built in one place for training and deployment.

    The cell's observation plus the base's action and, if given, the policy's previous residual and the
    plan features; :class:`ResidualWrapper` (training) and
    :class:`drillgym.training.residual_policy.ResidualPolicyController` (deployment) both call it.
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
        raise ValueError(f"residual axes={axes!r}; choose from {RESIDUAL_AXES}")
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


class ResidualWrapper(gym.Wrapper):
    """Expose a residual action space over a base controller.

    Args:
        env: the drilling env (sim or real: only ``env.unwrapped.plan`` and the observation are used).
        base: the base controller or its spec (default ``"li2023"``, the paper's best setting).
        scale: residual action ±1 maps to ± ``scale`` of the env's action range (0.5: ±1 mm).
        residual_feed: let the residual slow the base's feed too, never speed it up (off: the base's feed is
            kept). Slowing is a force limiter, as in controlled material-removal-rate drilling; a faster
            feed would also shorten the episode and with it the summed deviation penalty, a shortcut that
            does not lower the mean deviation.
        axes: ``"lateral"`` (default): the residual moves the tip across the drill only (task x, y), as the
            compensators do; ``"xyz"``: along the three base axes (it can then plunge the drill).
        observe_prev_residual: add the policy's previous residual to the observation (``residual_prev``).
        observe_plan: add the plan's angle, feed, stick-out, cortical thickness and bone hardness (``plan``).
        mode: ``"add"`` or ``"gain"`` (:data:`RESIDUAL_MODES`).
        feed_ceiling: how fast the feed residual may drill (:data:`FEED_CEILINGS`).
        plan_support: ``(low, high)`` plan features (:func:`plan_support`): the plan the policy sees is
            clamped to them, so that outside its training ranges it acts as at their nearest edge
            instead of extrapolating (None: no clamping).
    """

    def __init__(
        self,
        env: gym.Env,
        base: Controller | str = "li2023",
        scale: float = 0.5,
        residual_feed: bool = False,
        axes: str = "lateral",
        observe_prev_residual: bool = False,
        observe_plan: bool = False,
        mode: str = "add",
        plan_support: tuple[np.ndarray, np.ndarray] | None = None,
        feed_ceiling: str = "base",
    ):
        super().__init__(env)
        check_mode(mode, feed_ceiling)
        self.mode = mode
        self.feed_ceiling = feed_ceiling
        if not 0.0 < scale <= 2.0:
            raise ValueError(f"scale={scale} must be in (0, 2]")
        self.base = make_controller(base) if isinstance(base, str) else base
        self.scale = float(scale)
        self.residual_feed = residual_feed
        self.axes = axes
        self.action_space = spaces.Box(-1.0, 1.0, (residual_dims(residual_feed, axes),), np.float32)
        self._R: np.ndarray | None = None
        obs_space = env.observation_space
        assert isinstance(obs_space, spaces.Dict)
        extra = {BASE_ACTION_KEY: spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)}
        if observe_prev_residual:
            extra[PREV_RESIDUAL_KEY] = spaces.Box(-1.0, 1.0, self.action_space.shape, np.float32)
        if observe_plan:
            extra[PLAN_KEY] = spaces.Box(0.0, PLAN_HIGH, dtype=np.float32)
        self.observe_prev_residual = observe_prev_residual
        self.observe_plan = observe_plan
        self.plan_support = plan_support
        self._plan = np.zeros(PLAN_HIGH.shape, dtype=np.float32)
        self.observation_space = spaces.Dict({**obs_space.spaces, **extra})
        self._base_action = np.zeros(ACTION_DIM, dtype=np.float32)
        self._n_residual = residual_dims(residual_feed, axes)
        self._prev_residual = np.zeros(self._n_residual, dtype=np.float32)

    def _augment(self, obs: dict[str, np.ndarray], episode_start: bool) -> dict[str, np.ndarray]:
        self._base_action, _ = self.base.predict(obs, episode_start=np.array([episode_start]))
        if episode_start:
            self._prev_residual = np.zeros(self._n_residual, dtype=np.float32)
        return augment(
            obs,
            self._base_action.copy(),
            self._prev_residual.copy() if self.observe_prev_residual else None,
            self._plan.copy() if self.observe_plan else None,
        )

    def reset(self, **kwargs: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset the env, hand the base controller the new plan, return the augmented observation."""
        obs, info = self.env.reset(**kwargs)
        plan = self.env.unwrapped.plan  # type: ignore[attr-defined]
        self.base.set_plan(plan)
        self._plan = plan_features(plan, self.plan_support)
        self._R = plan.R_base_task if self.axes == "lateral" else None
        return self._augment(obs, True), info

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Apply ``base + scale · residual``; the info records both parts."""
        residual = np.asarray(action, dtype=np.float64)
        if residual.shape != self.action_space.shape:
            raise ValueError(f"residual action must have shape {self.action_space.shape}, got {residual.shape}")
        if not np.all(np.isfinite(residual)):
            raise ValueError(f"residual action {residual.tolist()} contains NaN or inf")
        total = combine(self._base_action, residual, self.scale, self._R, self.mode, self.feed_ceiling)
        self._prev_residual = np.clip(residual, -1.0, 1.0).astype(np.float32)
        obs, reward, terminated, truncated, info = self.env.step(total)
        info = {**info, "base_action": self._base_action.copy(), "residual_action": residual.astype(np.float32)}
        return self._augment(obs, False), float(reward), terminated, truncated, info
