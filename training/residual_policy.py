"""A trained residual policy as a controller: base controller + scaled SB3 residual, SB3 ``predict``.

``make_controller("residual:PATH")`` builds one; it runs wherever the base controller runs (the
observation holds only real-cell signals), on the simulated and on the real cell alike.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.registry import make_controller
from drillgym.envs.plan import DrillPlan
from drillgym.training.domain_randomization import merged_ranges
from drillgym.training.policy_bundle import load_bundle, resolve_policy
from drillgym.training.residual_wrapper import (
    PLAN_KEY,
    PREV_RESIDUAL_KEY,
    augment,
    combine,
    plan_features,
    plan_support,
)


class ResidualPolicyController(Controller):
    """``clip(base(obs) + scale · π(normalise(obs + base action)))``, π deterministic.

    A ``gain`` residual instead scales the base's correction across the drill by ``1 + scale · π(...)``.
    """

    name = "residual"

    def __init__(self, path: Path | str) -> None:
        super().__init__()
        _single_thread_inference()
        self.path = resolve_policy(str(path))
        self.bundle = load_bundle(self.path)
        self.base = make_controller(self.bundle.config.base)
        self.config = self.bundle.config
        spaces = getattr(self.bundle.model.observation_space, "spaces", {})
        prev = spaces.get(PREV_RESIDUAL_KEY)
        self._prev_shape = None if prev is None else prev.shape
        self._observes_plan = PLAN_KEY in spaces
        self._plan_support = plan_support(merged_ranges(self.config.dr_ranges))

    def set_plan(self, plan: DrillPlan) -> None:
        """The base controller gets the plan too."""
        self.base.set_plan(plan)
        super().set_plan(plan)

    def reset(self) -> None:
        """Mark an episode start: the base controller resets on its next call."""
        self._start = True
        self._prev_residual: np.ndarray | None = None

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Base action plus the policy's residual."""
        base_action, _ = self.base.predict(obs, episode_start=np.array([self._start]))
        self._start = False
        prev = None
        if self._prev_shape is not None:
            prev = self._prev_residual if self._prev_residual is not None else np.zeros(self._prev_shape, np.float32)
        plan = None
        if self._observes_plan:
            if self.plan is None:
                raise RuntimeError("this residual policy observes the plan: call set_plan(plan) first")
            plan = plan_features(self.plan, self._plan_support)
        aug = augment(obs, base_action, prev, plan)
        if self.bundle.normalizer is not None:
            aug = self.bundle.normalizer(aug)
        residual, _ = self.bundle.model.predict(aug, deterministic=True)
        residual = np.clip(np.asarray(residual, dtype=np.float32).reshape(-1), -1.0, 1.0)
        self._prev_residual = residual
        R = self.plan.R_base_task if self.config.residual_axes == "lateral" and self.plan is not None else None
        return combine(
            base_action,
            residual,
            self.config.residual_scale,
            R,
            self.config.residual_mode,
            self.config.residual_feed_ceiling,
        )

    def describe(self) -> dict[str, Any]:
        """Name, file and training configuration."""
        return {"name": "residual", "config": {"path": str(self.path), **self.config.to_dict()}}


def _single_thread_inference() -> None:
    """Run torch on one thread in this process.

    The policy is a small MLP that gains nothing from intra-op threads, and their spin-waiting takes CPU
    from the real cell's servo thread (and from the other benchmark workers).
    """
    import torch

    if torch.get_num_threads() > 1:
        torch.set_num_threads(1)


def load_residual_controller(path: str) -> ResidualPolicyController:
    """``residual:PATH`` -> controller (used by :func:`drillgym.controllers.make_controller`)."""
    if not path:
        raise ValueError("residual controllers need a path: residual:PATH/TO/policy.zip")
    return ResidualPolicyController(path)
