"""Training env of a schedule residual: one step is one hole, drilled with the tuning the agent chose.

:class:`ScheduleEnv` is a one-step Gymnasium env (a contextual bandit). ``reset`` draws the hole's scenario
(inside the training ranges, or the paper scenario with ``paper_share``) and an episode seed, and observes
the plan's normalised features (:func:`drillgym.controllers.plan_schedule.normalized_plan`); ``step(action)``
drills the hole with the base controller tuned by ``action``
(:class:`drillgym.controllers.plan_schedule.PlanScheduledController`) and ends the episode. The base
controller drills the same scenario on the same seed (the same specimen and noise), and the reward is the
difference, in the benchmark's own terms (:func:`paired_schedule_reward`): with a zero action the reward is
exactly 0. One decision per hole from what is known before drilling leaves the learner no credit to assign
across a thousand steps, and the pairing removes the specimen-to-specimen swing that hides a gain of a few
per cent.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec, normalized_plan
from drillgym.controllers.residual import PLAN_HIGH
from drillgym.controllers.rollout import run_episode
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.effects.registry import build_effects
from drillgym.envs.errors import UserError
from drillgym.training.cell import TrainingCell, with_cell
from drillgym.training.domain_randomization import DR_RANGES
from drillgym.training.schedule_holes import Hole, HoleDraws


@dataclass(frozen=True)
class ScheduleReward:
    """Weights of the paired hole reward (:func:`paired_schedule_reward`).

    Attributes:
        force_weight: cost of each relative rise of the peak lateral force above the base's, in units of relative
            deviation (3: a peak 1 % higher costs as much as a deviation 3 % higher). A lower peak earns nothing.
        time_weight: cost of each relative rise of the drill time beyond ``time_free`` (relative deviation units).
        time_free: relative drill-time rise over the base that costs nothing (0.2: +20 %).
        deviation_floor_mm: added to the base's deviation in the relative deviation change, so that a hole the
            base drills almost exactly does not dominate the reward (mm).
    """

    force_weight: float = 3.0
    time_weight: float = 2.0
    time_free: float = 0.2
    deviation_floor_mm: float = 0.01

    def __post_init__(self) -> None:
        if min(self.force_weight, self.time_weight, self.time_free) < 0.0 or self.deviation_floor_mm <= 0.0:
            raise UserError(f"schedule reward weights must be >= 0 and the floor > 0: {self}")


def paired_schedule_reward(agent: dict[str, float], base: dict[str, float], w: ScheduleReward) -> float:
    """Reward of one hole drilled by the agent's tuning against the base's on the same seed.

    ``−Δdev / (dev_base + floor) − force_weight · max(ΔF / F_base, 0) − time_weight · max(Δt / t_base − time_free, 0)``,
    from the episodes' ``deviation_mean_mm``, ``lateral_force_max_n`` and ``drill_time_s``: lower deviation
    earns, a higher peak force or a much longer drill costs. 0 when the two holes are the same.
    """
    dev = (agent["deviation_mean_mm"] - base["deviation_mean_mm"]) / (base["deviation_mean_mm"] + w.deviation_floor_mm)
    force = max(
        (agent["lateral_force_max_n"] - base["lateral_force_max_n"]) / max(base["lateral_force_max_n"], 1e-6), 0.0
    )
    time = max((agent["drill_time_s"] - base["drill_time_s"]) / max(base["drill_time_s"], 1e-6) - w.time_free, 0.0)
    out = -dev - w.force_weight * force - w.time_weight * time
    return float(out) if np.isfinite(out) else -10.0


def is_base_tuning(action: np.ndarray) -> bool:
    """Whether ``action`` (clipped to [-1, 1]) leaves every field at the base's value: the hole is the base's own."""
    return bool(np.all(np.clip(action, -1.0, 1.0) == 0.0))


def hole_outcome(
    spec: ScheduleSpec,
    weights: ScheduleReward,
    hole: Hole,
    action: np.ndarray,
    agent: dict[str, float],
    base: dict[str, float],
) -> tuple[float, dict[str, Any]]:
    """The paired reward and the info of ``hole`` drilled with ``action``'s tuning and by the base.

    ``agent`` and ``base`` are the two episodes' metrics (the base's are the agent's when the tuning is the base's).
    """
    info = {
        "scenario": dict(hole.scenario),
        "episode_seed": hole.episode_seed,
        "metrics": agent,
        "base": base,
        "tuned_spec": spec.controller_spec(action),
        **({"cell": hole.cell_spec} if hole.cell_spec else {}),
    }
    return paired_schedule_reward(agent, base, weights), info


class ScheduleEnv(gym.Env):
    """One hole per episode: observe the plan, choose the base's tuning, be rewarded against the base.

    Args:
        spec: the base controller and the scheduled fields (its ``plan_support`` scales the observation).
        env_kwargs: arguments of the simulated env (reward weights are irrelevant here).
        ranges: domain-randomisation ranges (:data:`drillgym.training.domain_randomization.DR_RANGES`).
        paper_share: share of holes drilled in the env's own scenario (the paper's, by default).
        reward: the reward's weights.
        episodes: fixed ``(scenario, seed)`` holes to visit in turn instead of draws (evaluation: every visit of a
            hole replays it, so successive evaluations differ only by the policy).
        stream_keys: keys of the draws' generator (a run's seed and the worker's rank): the scenarios and episode
            seeds come from :func:`drillgym.envs.seeds.stream` ``(TRAIN, *stream_keys[, reset seed])``, and every
            drawn episode seed lies in the training namespace, never a judge episode's.

    ``info`` holds the hole's scenario, seed, both episodes' metrics (``metrics``: the agent's, ``base``) and the
    tuned spec.
    """

    def __init__(
        self,
        spec: ScheduleSpec,
        env_kwargs: dict[str, Any] | None = None,
        ranges: dict[str, tuple[float, float]] | None = None,
        paper_share: float = 0.0,
        reward: ScheduleReward | None = None,
        episodes: list[tuple[dict[str, Any], int]] | None = None,
        stream_keys: tuple[int, ...] = (),
        cell: TrainingCell | None = None,
    ) -> None:
        self.schedule = spec
        self.cell = cell or TrainingCell()
        self.sim = with_cell(gym.make(SIM_ENV_ID, **(env_kwargs or {})), self.cell)
        self.weights = reward or ScheduleReward()
        paper = dict(self.sim.unwrapped.scenario.to_dict())  # type: ignore[attr-defined]
        try:
            self.holes = HoleDraws(
                paper, DR_RANGES if ranges is None else ranges, paper_share, self.cell, episodes, stream_keys
            )
        except UserError:
            self.sim.close()
            raise
        self.observation_space = spaces.Box(-1.0, 1.0, PLAN_HIGH.shape, np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (spec.dims,), np.float32)
        self.hole: Hole | None = None
        """The current hole (drawn at reset; its effects drawn with the cell's ranges in training, else the cell's own)."""
        self.base = make_controller(spec.base)

    @property
    def scenario(self) -> dict[str, Any]:
        """The current hole's scenario (empty before the first reset)."""
        return {} if self.hole is None else self.hole.scenario

    @property
    def episode_seed(self) -> int:
        """The current hole's episode seed (-1 before the first reset)."""
        return -1 if self.hole is None else self.hole.episode_seed

    def _plan(self) -> np.ndarray:
        self.sim.reset(seed=self.episode_seed, options={"scenario": self.scenario})
        return normalized_plan(self.sim.unwrapped.plan, self.schedule.plan_support)  # type: ignore[attr-defined]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """Draw the hole's scenario and seed (``options["scenario"]`` fixes the scenario); observe its plan."""
        super().reset(seed=seed)
        self.holes.seed(seed)
        self.hole = self.holes.next((options or {}).get("scenario"))
        return self._plan(), {"scenario": dict(self.scenario), "episode_seed": self.episode_seed}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """Drill the hole with the tuning ``action`` and with the base; the paired reward; the episode ends."""
        if self.hole is None:
            raise RuntimeError("call reset() before step()")
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        tuned = PlanScheduledController(self.schedule, policy=lambda _obs: a)
        agent = run_episode(self.sim, tuned, self.episode_seed, keep_trace=False, options=self._options())
        if is_base_tuning(a):
            base = agent
        else:
            base = run_episode(self.sim, self.base, self.episode_seed, keep_trace=False, options=self._options())
        reward, info = hole_outcome(self.schedule, self.weights, self.hole, a, agent.metrics, base.metrics)
        obs = normalized_plan(self.sim.unwrapped.plan, self.schedule.plan_support)  # type: ignore[attr-defined]
        return obs, reward, True, False, info

    def _options(self) -> dict[str, Any]:
        """The hole's reset options: its scenario, and its drawn effects (each run gets its own effect objects)."""
        assert self.hole is not None
        if not self.cell.ranges:  # the cell's own effects stay switched on in the env (with_cell)
            return {"scenario": self.hole.scenario}
        spec = self.hole.cell_spec
        return {"scenario": self.hole.scenario, "effects": build_effects(spec) if spec else []}

    def close(self) -> None:
        """Close the simulated env."""
        self.sim.close()
