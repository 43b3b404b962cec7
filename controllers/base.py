"""What every controller is: SB3's ``predict`` on top of a per-step ``act``.

A controller maps one observation of the cell (the Dict of :mod:`drillgym.envs.observation`) to one action
(``Box(-1, 1, (4,))``: tip correction in the base frame + feed override). It is told the surgical
plan (:class:`drillgym.envs.plan.DrillPlan`) before each episode and keeps its own state (filters, PID,
path prediction), reset at episode start.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Hashable, Sequence
from dataclasses import asdict, is_dataclass
from typing import Any, ClassVar

import numpy as np

from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan


class Controller(ABC):
    """Base class: ``set_plan`` then ``predict`` (SB3 protocol) or ``act`` step by step."""

    name: ClassVar[str] = "controller"
    batchable: bool = False
    """Whether :meth:`act_batch` steps several episodes of one plan at once (``set_plan(plan, num_episodes=N)``):
    what the batched rollout (:func:`drillgym.controllers.rollout.run_episodes`) uses instead of one copy per episode."""
    config: Any

    def __init__(self) -> None:
        self.plan: DrillPlan | None = None
        self.num_episodes = 1

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Tell the controller the planned hole and tool; resets its state.

        ``num_episodes`` > 1 (a :attr:`batchable` controller only): that many episodes of the plan, stepped
        together by :meth:`act_batch`.
        """
        if num_episodes != 1 and not self.batchable:
            raise UserError(f"{self.name} steps one episode at a time; got num_episodes={num_episodes}")
        if num_episodes < 1:
            raise UserError(f"num_episodes={num_episodes} must be >= 1")
        self.plan = plan
        self.num_episodes = num_episodes
        self.reset()

    @abstractmethod
    def reset(self) -> None:
        """Forget the previous episode (filters, integrators, queued corrections)."""

    @abstractmethod
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """One action (float32, shape (4,), in [-1, 1]) for one observation."""

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """:meth:`act` of every episode of a batch (observations (N, k), actions (N, 4)): batchable controllers."""
        raise NotImplementedError(f"{self.name} is not batchable")

    def stack_part(self) -> Controller:
        """The controller that does the stepping (a wrapper that only chose it returns the chosen one)."""
        return self

    def stack_key(self) -> Hashable | None:
        """What lets controllers step as one batch (:meth:`stack`); None: this one steps alone.

        Controllers (each set to its own plan, one episode) whose :meth:`stack_part` keys are equal stack.
        """
        return None

    @classmethod
    def stack(cls, controllers: Sequence[Controller]) -> Controller:
        """One controller stepping ``controllers`` (of equal :meth:`stack_key`) as a batch, row i the i-th's actions."""
        raise NotImplementedError(f"{cls.name} does not stack")

    def predict(
        self,
        observation: dict[str, np.ndarray],
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """SB3's ``PolicyPredictor.predict``: accepts one observation or a batch of one."""
        if self.plan is None:
            raise RuntimeError(f"{self.name}: call set_plan(env.unwrapped.plan) before predict()")
        batched = np.ndim(observation["path_depth_m"]) == 2
        if batched:
            if np.shape(observation["path_depth_m"])[0] != 1:
                raise UserError(
                    f"{self.name} is a single-env controller; got a batch of {len(observation['path_depth_m'])}"
                )
            observation = {k: np.asarray(v)[0] for k, v in observation.items()}
        if episode_start is not None and bool(np.any(episode_start)):
            self.reset()
        action = np.clip(np.asarray(self.act(observation), dtype=np.float32), -1.0, 1.0)
        if action.shape != (ACTION_DIM,):
            raise RuntimeError(f"{self.name} produced an action of shape {action.shape}")
        return (action[None] if batched else action), state

    def describe(self) -> dict[str, Any]:
        """Name and configuration, JSON-ready (written into every episode log)."""
        cfg = asdict(self.config) if is_dataclass(self.config) and not isinstance(self.config, type) else {}
        return {"name": self.name, "config": {k: _jsonable(v) for k, v in cfg.items()}}


def stack_controllers(controllers: Sequence[Any]) -> list[tuple[list[int], Any]]:
    """Group policies that can step as one batch: ``(indices, policy)`` pairs covering every index once.

    Controllers with an equal :meth:`Controller.stack_key` (of their :meth:`~Controller.stack_part`) become one
    stacked controller over their indices, in order; any other policy (a trained model, a controller that does not
    stack) stays alone.
    """
    groups: dict[Hashable, list[int]] = {}
    alone: list[tuple[list[int], Any]] = []
    for i, c in enumerate(controllers):
        key = c.stack_part().stack_key() if isinstance(c, Controller) else None
        if key is None:
            alone.append(([i], c))
        else:
            groups.setdefault(key, []).append(i)
    stacked = []
    for idx in groups.values():
        parts = [controllers[i].stack_part() for i in idx]
        stacked.append((idx, type(parts[0]).stack(parts)))
    return stacked + alone


def _jsonable(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, tuple):
        return list(v)
    return v
