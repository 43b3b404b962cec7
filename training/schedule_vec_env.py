"""A schedule residual's holes, many at once on the batched engine: Stable-Baselines3's ``VecEnv`` API.

:class:`ScheduleVecEnv` is ``n`` copies of the one-hole env (:class:`drillgym.training.schedule_env.ScheduleEnv`) in
one process: slot ``j`` draws the holes worker ``j`` of a ``SubprocVecEnv`` of them would draw (the same
:class:`~drillgym.training.schedule_holes.HoleDraws`, keyed by the run's seed and ``j``), and every step drills all
``n`` holes twice, with the tuning the agent chose and with the base, as ``2n`` episodes of one
:class:`~drillgym.envs.batched.BatchedDrillEnv`. Each episode's metrics are the single env's, so the rewards,
observations and infos are those of the one-hole envs, bit for bit (``tests/training/test_schedule_vec_env.py``),
and a run with ``n`` slots learns what a run with ``n`` workers learns. It runs in one process: its speed comes
from stepping all ``2n`` episodes per compiled call, not from more cores. Wrap it in SB3's ``VecMonitor``.

A cell whose effects are drawn per hole (a training cell with ranges, ``drillgym train --cell-from-diagnosis``)
gives each slot its hole's effects (``BatchedDrillEnv.reset(options={"effects": ...})``); a cell with effects the
compiled step does not run keeps the one-hole envs (:func:`drillgym.training.env_factory.batched_schedule`).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec, normalized_plan
from drillgym.controllers.residual import PLAN_HIGH
from drillgym.controllers.rollout import run_batch
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.errors import UserError
from drillgym.training.cell import TrainingCell
from drillgym.training.domain_randomization import DR_RANGES
from drillgym.training.remote import Remote
from drillgym.training.schedule_env import ScheduleReward, hole_outcome, is_base_tuning
from drillgym.training.schedule_holes import Hole, HoleDraws


class HoleBatch:
    """Slots ``first .. first + count - 1`` of ``total``: their holes drawn, drilled twice each, rewarded.

    The unit of work of :class:`ScheduleVecEnv`, in its process or in a worker's (:class:`~drillgym.training.remote.Remote`).
    Arguments as :class:`ScheduleVecEnv`'s.
    """

    def __init__(
        self,
        first: int,
        count: int,
        total: int,
        spec: ScheduleSpec,
        env_kwargs: dict[str, Any] | None,
        ranges: dict[str, tuple[float, float]],
        paper_share: float,
        reward: ScheduleReward,
        episodes: list[tuple[dict[str, Any], int]] | None,
        run_seed: int,
        cell: TrainingCell,
    ) -> None:
        self.count = count
        self.schedule = spec
        self.weights = reward
        self.batch = BatchedDrillEnv(2 * count, autoreset=False, effects=cell.nominal_spec(), **(env_kwargs or {}))
        paper = dict(self.batch.scenario.to_dict())
        try:
            self.holes = [
                HoleDraws(paper, ranges, paper_share, cell, episodes, (run_seed, j), first=j, stride=total)
                for j in range(first, first + count)
            ]
        except UserError:
            self.batch.close()
            raise
        self.current: list[Hole] = []
        self.bases = [make_controller(spec.base) for _ in range(count)]
        self._started: dict[str, np.ndarray] | None = None

    def start(self, seeds: Sequence[int | None] | None = None) -> tuple[np.ndarray, list[dict[str, Any]]]:
        """Draw each slot's next hole (reseeding its draws first where ``seeds`` says), reset the batch on them.

        Returns the plans' observations and the holes' reset infos.
        """
        for j, draws in enumerate(self.holes):
            if seeds is not None:
                draws.seed(seeds[j])
        self.current = [draws.next() for draws in self.holes]
        scenarios = [h.scenario for h in self.current] * 2
        effects = [h.cell_spec for h in self.current] * 2  # a ranged cell's draws: the hole's own, for both runs
        seeds_: list[int | None] = []
        seeds_ += [h.episode_seed for h in self.current] * 2
        self._started, _ = self.batch.reset(seed=seeds_, options={"scenario": scenarios, "effects": effects})
        infos = [{"scenario": dict(h.scenario), "episode_seed": h.episode_seed} for h in self.current]
        return self._plans(), infos

    def _plans(self) -> np.ndarray:
        support = self.schedule.plan_support
        return np.stack([normalized_plan(self.batch.envs[j].plan, support) for j in range(self.count)])

    def drill(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]]]:
        """Drill every hole with its tuning (count, fields) and with the base; start the next holes.

        Returns the next holes' plans, the paired rewards and each ended hole's info.
        """
        if self._started is None:
            raise RuntimeError("drill() before start()")
        n = self.count
        tuned = [PlanScheduledController(self.schedule, policy=_fixed(actions[j])) for j in range(n)]
        seeds = [h.episode_seed for h in self.current] * 2
        results = run_batch(self.batch, [*tuned, *self.bases], seeds, started=self._started)
        self._started = None
        ended = self._plans()
        rewards = np.zeros(n)
        infos: list[dict[str, Any]] = []
        for j, hole in enumerate(self.current):
            agent = results[j]
            base = agent if is_base_tuning(actions[j]) else results[n + j]
            rewards[j], info = hole_outcome(self.schedule, self.weights, hole, actions[j], agent.metrics, base.metrics)
            infos.append({**info, "TimeLimit.truncated": False, "terminal_observation": ended[j]})
        obs, _ = self.start()
        return obs, rewards, infos

    def close(self) -> None:
        """Close the batched env."""
        self.batch.close()


class ScheduleVecEnv(VecEnv):
    """``num_envs`` one-hole envs stepped together (see the module docstring).

    Args:
        num_envs: holes per step (slots).
        spec, env_kwargs, ranges, paper_share, reward, cell: as :class:`~drillgym.training.schedule_env.ScheduleEnv`.
        episodes: fixed ``(scenario changes, seed)`` holes: slot ``j`` visits ``j, j + n, j + 2n, ...`` of them (with
            ``n`` the list's length every reset visits each hole once).
        run_seed: the run's seed: slot ``j`` draws from the stream of ``(run_seed, j)``.
        workers: processes drilling the slots (this one and ``workers - 1`` spawned ones, each a contiguous share of
            the slots): the same holes and numbers with any number.
    """

    def __init__(
        self,
        num_envs: int,
        spec: ScheduleSpec,
        env_kwargs: dict[str, Any] | None = None,
        ranges: dict[str, tuple[float, float]] | None = None,
        paper_share: float = 0.0,
        reward: ScheduleReward | None = None,
        episodes: list[tuple[dict[str, Any], int]] | None = None,
        run_seed: int = 0,
        cell: TrainingCell | None = None,
        workers: int = 1,
    ) -> None:
        if not isinstance(num_envs, int) or num_envs < 1:
            raise UserError(f"num_envs={num_envs!r} must be an integer >= 1")
        if not isinstance(workers, int) or workers < 1:
            raise UserError(f"workers={workers!r} must be an integer >= 1")
        cell = cell or TrainingCell()
        common: dict[str, Any] = {
            "total": num_envs,
            "spec": spec,
            "env_kwargs": env_kwargs,
            "ranges": dict(DR_RANGES if ranges is None else ranges),
            "paper_share": paper_share,
            "reward": reward or ScheduleReward(),
            "episodes": episodes,
            "run_seed": run_seed,
            "cell": cell,
        }
        shares = np.array_split(np.arange(num_envs), min(workers, num_envs))
        self.here = HoleBatch(int(shares[0][0]), len(shares[0]), **common)
        self.remotes: list[Remote] = []
        try:
            for share in shares[1:]:
                self.remotes.append(Remote(HoleBatch, {"first": int(share[0]), "count": len(share), **common}))
        except BaseException:
            self.close()
            raise
        self._sizes = [len(share) for share in shares]
        self._actions: np.ndarray | None = None
        self._ready = False
        self.render_mode = None  # nothing to render (SB3 asks)
        obs_space = spaces.Box(-1.0, 1.0, PLAN_HIGH.shape, np.float32)
        super().__init__(num_envs, obs_space, spaces.Box(-1.0, 1.0, (spec.dims,), np.float32))

    def _all(self, method: str, per_share: list[Any]) -> list[Any]:
        """``method(arg)`` on every share (the workers' first, then this process's, then their answers), in order."""
        for remote, arg in zip(self.remotes, per_share[1:], strict=True):
            remote.send(method, arg)
        try:
            here = getattr(self.here, method)(per_share[0])
        finally:  # every worker's answer is collected, even after an error here (none is left in a pipe)
            answers, errors = [], []
            for remote in self.remotes:
                try:
                    answers.append(remote.receive())
                except Exception as exc:
                    errors.append(exc)
        if errors:
            raise errors[0]
        return [here, *answers]

    def _split(self, rows: Any) -> list[Any]:
        bounds = np.cumsum([0, *self._sizes])
        return [rows[a:b] for a, b in itertools.pairwise(bounds)]

    # ------------------------------------------------------------------ SB3 API
    def reset(self) -> VecEnvObs:
        """Draw every slot's hole (with the seeds of :meth:`seed`, if set) and observe the plans."""
        if any(self._options):
            raise UserError(f"ScheduleVecEnv takes no reset options, got {self._options}")
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        parts = self._all("start", self._split(seeds) if seeds is not None else [None] * len(self._sizes))
        self.reset_infos = [info for _, infos in parts for info in infos]
        self._reset_seeds()
        self._reset_options()
        self._ready = True
        return np.concatenate([obs for obs, _ in parts])

    def step_async(self, actions: np.ndarray) -> None:
        """Remember the tunings (n, fields) for :meth:`step_wait`."""
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        """Drill every hole with its tuning and with the base; the paired rewards; the next holes' plans."""
        if self._actions is None or not self._ready:
            raise RuntimeError("step_wait() without reset() and step_async()")
        actions = np.asarray(self._actions, dtype=np.float64).reshape(self.num_envs, -1)
        self._actions = None
        parts = self._all("drill", self._split(actions))
        obs = np.concatenate([p[0] for p in parts])
        rewards = np.concatenate([p[1] for p in parts])
        infos = [info for p in parts for info in p[2]]
        return obs, rewards, np.ones(self.num_envs, dtype=bool), infos

    def close(self) -> None:
        """Close the batched envs and end the worker processes."""
        for remote in getattr(self, "remotes", []):
            remote.close()
        if hasattr(self, "here"):
            self.here.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """This env's attribute, once per selected slot (the slots share one env)."""
        value = getattr(self, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Not supported: the slots share one env."""
        raise NotImplementedError(f"ScheduleVecEnv's slots share one env: set {attr_name} on it")

    def env_method(
        self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any
    ) -> list[Any]:
        """Call this env's method once, for every selected slot (one result each)."""
        result = getattr(self, method_name)(*method_args, **method_kwargs)
        return [result for _ in self._get_indices(indices)]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices: VecEnvIndices = None) -> list[bool]:
        """False: the slots are not single Gymnasium envs that could be wrapped (wrap this in ``VecMonitor``)."""
        return [False for _ in self._get_indices(indices)]


def _fixed(action: np.ndarray) -> Any:
    """A schedule policy that returns ``action`` whatever the plan."""
    a = np.array(action, dtype=np.float64)
    return lambda _obs: a
