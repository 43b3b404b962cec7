"""A trained residual policy as a controller.

:class:`drillgym.controllers.residual.ResidualController` over the saved bundle's base controller, with the
bundle's SB3 model (deterministic) as its policy.

``make_controller("residual:PATH")`` builds one; it runs wherever the base controller runs (the
observation holds only real-cell signals), on the simulated and on the real cell alike.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.controllers.plan_schedule import PlanScheduledController
from drillgym.controllers.registry import make_controller
from drillgym.controllers.residual import PLAN_KEY, PREV_RESIDUAL_KEY, ResidualController, ResidualSpec
from drillgym.envs.errors import UserError
from drillgym.training.config import TrainConfig
from drillgym.training.domain_randomization import training_plan_support
from drillgym.training.policy_bundle import PolicyBundle, bundle_paths, load_bundle, resolve_policy


class BundlePolicy:
    """A saved policy as a function: normalise the observation, SB3 ``predict`` (deterministic), clip to [-1, 1]."""

    def __init__(self, bundle: PolicyBundle) -> None:
        self.bundle = bundle

    def __call__(self, obs: Any) -> np.ndarray:
        """The residual for one policy observation (a dict, or a schedule policy's plan features)."""
        if self.bundle.normalizer is not None:
            obs = self.bundle.normalizer(obs)
        residual, _ = self.bundle.policy.predict(obs, deterministic=True)
        return np.clip(np.asarray(residual, dtype=np.float32).reshape(-1), -1.0, 1.0)


def residual_spec(cfg: TrainConfig) -> ResidualSpec:
    """The residual a training configuration describes (its plan support from its training ranges)."""
    return ResidualSpec(
        scale=cfg.residual_scale,
        mode=cfg.residual_mode,
        axes=cfg.residual_axes,
        residual_feed=cfg.residual_feed,
        feed_ceiling=cfg.residual_feed_ceiling,
        observe_prev_residual=cfg.observe_prev_residual,
        observe_plan=cfg.observe_plan,
        plan_support=training_plan_support(cfg.dr_ranges),
    )


def _single_thread_inference() -> None:
    """Run torch on one thread in this process.

    The policy is a small MLP that gains nothing from intra-op threads, and their spin-waiting takes CPU
    from the real cell's servo thread (and from the other benchmark workers).
    """
    import torch

    if torch.get_num_threads() > 1:
        torch.set_num_threads(1)


_BUNDLES: dict[tuple[str, tuple[int, ...]], PolicyBundle] = {}
"""Bundles loaded in this process, by path and their files' sizes and modification times."""


def _loaded(resolved: Path | str) -> PolicyBundle:
    """:func:`load_bundle`, once per process for the same files (a batch builds one controller per episode).

    The bundle is shared: its model predicts without state and its normaliser's statistics are fixed.
    """
    files = [p for p in bundle_paths(Path(resolved)) if p.exists()]
    key = (str(resolved), tuple(v for p in files for v in (p.stat().st_size, p.stat().st_mtime_ns)))
    if key not in _BUNDLES:
        _BUNDLES[key] = load_bundle(resolved)
    return _BUNDLES[key]


def load_residual_controller(path: Path | str) -> ResidualController | PlanScheduledController:
    """``residual:PATH`` (or a shipped policy's name) -> controller (used by :func:`drillgym.controllers.make_controller`).

    A ``schedule`` bundle gives a :class:`drillgym.controllers.plan_schedule.PlanScheduledController`: its
    policy tunes the base once per hole from the plan.
    """
    if not str(path):
        raise UserError("residual controllers need a path: residual:PATH/TO/policy.zip")
    _single_thread_inference()
    resolved = resolve_policy(str(path))
    bundle = _loaded(resolved)
    spaces = getattr(bundle.policy.observation_space, "spaces", {})
    cfg = bundle.config
    if cfg.schedule:
        return PlanScheduledController(
            cfg.schedule_spec(), BundlePolicy(bundle), {"path": str(resolved), **cfg.to_dict()}
        )
    # What the saved model observes decides, as its observation space was built from it.
    spec = replace(
        residual_spec(cfg), observe_prev_residual=PREV_RESIDUAL_KEY in spaces, observe_plan=PLAN_KEY in spaces
    )
    return ResidualController(
        make_controller(cfg.base), spec, BundlePolicy(bundle), {"path": str(resolved), **cfg.to_dict()}
    )
