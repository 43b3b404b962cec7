"""Residual RL on top of a classical compensator: the RL agent's action is the residual.

:class:`ResidualWrapper` is a Gymnasium wrapper around a :class:`drillgym.controllers.residual.ResidualController`
without a policy: at every step the controller runs its base controller and builds the policy's observation
(the cell's observation, the base's action, optionally the previous residual and the plan), and the
agent's action is combined with the base's as a deployed policy's would be. With a residual of zero the
wrapped env behaves exactly as the base controller does: the policy starts from the baseline.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.controllers import Controller, make_controller
from drillgym.controllers.residual import (
    BASE_ACTION_KEY,
    PLAN_HIGH,
    PLAN_KEY,
    PREV_RESIDUAL_KEY,
    ResidualController,
    ResidualSpec,
)
from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.errors import UserError


class ResidualWrapper(gym.Wrapper):
    """Expose a residual action space over a base controller.

    Args:
        env: the drilling env (sim or real: only ``env.unwrapped.plan`` and the observation are used).
        base: the base controller or its spec (default ``"li2023"``, the paper's best setting).
        scale, residual_feed, axes, observe_prev_residual, observe_plan, mode, plan_support, feed_ceiling:
            the residual (:class:`drillgym.controllers.residual.ResidualSpec`). A feed residual slows the
            base's feed and never speeds it up beyond ``feed_ceiling``: slowing is a force limiter, as in
            controlled material-removal-rate drilling; a faster feed would also shorten the episode and
            with it the summed deviation penalty, a shortcut that does not lower the mean deviation.
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
        spec = ResidualSpec(
            float(scale), mode, axes, residual_feed, feed_ceiling, observe_prev_residual, observe_plan, plan_support
        )
        self.controller = ResidualController(make_controller(base) if isinstance(base, str) else base, spec)
        self.action_space = spaces.Box(-1.0, 1.0, (spec.dims,), np.float32)
        obs_space = env.observation_space
        assert isinstance(obs_space, spaces.Dict)
        extra = {BASE_ACTION_KEY: spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)}
        if observe_prev_residual:
            extra[PREV_RESIDUAL_KEY] = spaces.Box(-1.0, 1.0, self.action_space.shape, np.float32)
        if observe_plan:
            extra[PLAN_KEY] = spaces.Box(0.0, PLAN_HIGH, dtype=np.float32)
        self.observation_space = spaces.Dict({**obs_space.spaces, **extra})

    @property
    def base(self) -> Controller:
        """The base controller."""
        return self.controller.base

    @property
    def residual_spec(self) -> ResidualSpec:
        """How the residual acts and what the policy observes."""
        return self.controller.spec

    def reset(self, **kwargs: Any) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset the env, hand the controller the new plan, return the policy's observation."""
        obs, info = self.env.reset(**kwargs)
        self.controller.set_plan(self.env.unwrapped.plan)  # type: ignore[attr-defined]
        return self.controller.observe(obs), info

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Apply the base's action with the residual ``action``; the info records both parts."""
        residual = np.asarray(action, dtype=np.float64)
        if residual.shape != self.action_space.shape:
            raise UserError(f"residual action must have shape {self.action_space.shape}, got {residual.shape}")
        base_action = self.controller.base_action.copy()
        total = self.controller.compose(residual)
        obs, reward, terminated, truncated, info = self.env.step(total)
        info = {**info, "base_action": base_action, "residual_action": residual.astype(np.float32)}
        return self.controller.observe(obs), float(reward), terminated, truncated, info
