"""Environments for residual training and evaluation (SB3 vectorised, monitored)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any

import gymnasium as gym
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecEnv, VecMonitor

from drillgym.envs import SIM_ENV_ID
from drillgym.envs.seeds import Purpose, episode_seed
from drillgym.training.cell import CellDraws, with_cell
from drillgym.training.config import TrainConfig
from drillgym.training.domain_randomization import (
    VALIDATION_SEED,
    DomainRandomization,
    ScenarioCycle,
    merged_ranges,
    training_plan_support,
    validation_scenarios,
)
from drillgym.training.paired_reward import PairedReward
from drillgym.training.residual_wrapper import ResidualWrapper
from drillgym.training.schedule_env import ScheduleEnv
from drillgym.training.schedule_vec_env import ScheduleVecEnv
from drillgym.training.selection import validation_episodes

ENV_ID = SIM_ENV_ID
EVAL_SEED = 10_000
"""Index of the evaluation env's seed in the selection namespace (plus the run's seed for step-level runs; plus the
hole's index for schedule runs; :mod:`drillgym.envs.seeds`)."""


def wrap_residual(env: gym.Env, cfg: TrainConfig) -> ResidualWrapper:
    """``env`` under the residual wrapper configured by ``cfg``."""
    return ResidualWrapper(
        env,
        cfg.base,
        cfg.residual_scale,
        cfg.residual_feed,
        cfg.residual_axes,
        cfg.observe_prev_residual,
        cfg.observe_plan,
        cfg.residual_mode,
        training_plan_support(cfg.dr_ranges),
        cfg.residual_feed_ceiling,
    )


def residual_env(cfg: TrainConfig, randomize: bool, scenario: dict[str, Any] | None = None, rank: int = 0) -> gym.Env:
    """One drilling env (optionally domain-randomised, then with ``cfg.paired_reward``) under the residual wrapper.

    A randomised env draws from the training stream of ``(cfg.seed, rank)`` (:mod:`drillgym.envs.seeds`).
    """
    cell = cfg.training_cell()
    env: gym.Env = with_cell(gym.make(ENV_ID, **{**cfg.env_kwargs, **(scenario or {})}), cell)
    if randomize:
        keys = (cfg.seed, rank)
        env = DomainRandomization(env, merged_ranges(cfg.dr_ranges), cfg.paper_share, stream_keys=keys)
        if cell.ranges:
            env = CellDraws(env, cell, stream_keys=keys)
        if cfg.paired_reward:
            env = PairedReward(
                env, cfg.base, lambda: with_cell(gym.make(ENV_ID, **cfg.env_kwargs), cell), stream_keys=keys
            )
    return wrap_residual(env, cfg)


def schedule_env(
    cfg: TrainConfig, episodes: list[tuple[dict[str, Any], int]] | None = None, rank: int = 0
) -> ScheduleEnv:
    """The one-hole-per-step env of a ``schedule`` run (draws inside the training ranges, or ``episodes`` in turn).

    Draws come from the training stream of ``(cfg.seed, rank)`` (:mod:`drillgym.envs.seeds`).
    """
    return ScheduleEnv(**_schedule_args(cfg), episodes=episodes, stream_keys=(cfg.seed, rank))


def _schedule_args(cfg: TrainConfig) -> dict[str, Any]:
    """A schedule env's arguments from the configuration: spec, env arguments, ranges, paper share, reward, cell."""
    return {
        "spec": cfg.schedule_spec(),
        "env_kwargs": cfg.env_kwargs,
        "ranges": merged_ranges(cfg.dr_ranges),
        "paper_share": cfg.paper_share if cfg.domain_randomization else 1.0,
        "reward": cfg.schedule_weights(),
        "cell": cfg.training_cell(),
    }


def _schedule_eval_episodes(cfg: TrainConfig, scenario: dict[str, Any] | None) -> list[tuple[dict[str, Any], int]]:
    """The (scenario, seed) holes a ``schedule`` run is evaluated on, as the step-level evaluation's episodes.

    ``validation``: the validation draws and their seeds (:func:`drillgym.training.selection.validation_episodes`,
    the first ``cfg.eval_episodes``); ``paper`` (or a given ``scenario``): that scenario on ``cfg.eval_episodes``
    selection seeds from :data:`EVAL_SEED`.
    """
    if cfg.eval_scenarios == "validation" and scenario is None:
        return validation_episodes(cfg)[: cfg.eval_episodes]
    return [(dict(scenario or {}), episode_seed(Purpose.SELECT, EVAL_SEED + i)) for i in range(cfg.eval_episodes)]


def _train_env(cfg: TrainConfig, rank: int) -> gym.Env:
    """Worker ``rank``'s training env, monitored as SB3's ``make_vec_env`` does."""
    env: gym.Env = (
        schedule_env(cfg, rank=rank) if cfg.schedule else residual_env(cfg, cfg.domain_randomization, rank=rank)
    )
    return Monitor(env)


def batched_schedule(cfg: TrainConfig) -> bool:
    """Whether a ``schedule`` run's holes run on the batched engine (:class:`ScheduleVecEnv`).

    Always, but where the cell has effects the compiled step does not run: those keep one-hole envs. Both give the
    same holes, rewards and observations (a cell drawn per hole too: each slot runs its hole's draw).
    """
    if not cfg.schedule:
        return False
    return cfg.training_cell().compiled


def schedule_vec_env(
    cfg: TrainConfig, num_envs: int, episodes: list[tuple[dict[str, Any], int]] | None = None
) -> VecEnv:
    """``num_envs`` holes at once on the batched engine, monitored (SB3's ``VecMonitor``); see :func:`schedule_env`."""
    env = ScheduleVecEnv(num_envs, **_schedule_args(cfg), episodes=episodes, run_seed=cfg.seed, workers=cfg.env_workers)
    return VecMonitor(env)


def make_train_vec_env(cfg: TrainConfig) -> VecEnv:
    """``cfg.n_envs`` randomised envs: SubprocVecEnv (spawned workers) when more than one.

    Worker ``rank`` draws its episodes from its own stream, keyed by ``(cfg.seed, rank)``
    (:mod:`drillgym.envs.seeds`): runs ``s`` and ``s + 1`` share no worker's episodes (SB3's ``make_vec_env``
    would seed worker ``r`` with ``s + r``). A ``schedule`` run's ``n_envs`` holes run in this process on the
    batched engine instead (:func:`batched_schedule`), slot ``r`` drawing worker ``r``'s holes.
    """
    if batched_schedule(cfg):
        return schedule_vec_env(cfg, cfg.n_envs)
    factories: list[Callable[[], gym.Env]] = [functools.partial(_train_env, cfg, rank) for rank in range(cfg.n_envs)]
    if cfg.n_envs > 1:
        return SubprocVecEnv(factories, start_method="spawn")
    return DummyVecEnv(factories)


def make_eval_vec_env(cfg: TrainConfig, scenario: dict[str, Any] | None = None) -> VecEnv:
    """The evaluation env under the residual wrapper (one env).

    ``cfg.eval_scenarios == "paper"``: the paper scenario (or ``scenario``) every episode;
    ``"validation"``: :func:`drillgym.training.domain_randomization.validation_scenarios` in turn, one per
    evaluation episode, each with its own fixed seed (so every evaluation of ``cfg.eval_episodes``
    episodes replays the same episodes: evaluations, and the base's, differ only by the policy).
    """
    if batched_schedule(cfg):  # every evaluation: each fixed hole once, all in one batch
        holes = _schedule_eval_episodes(cfg, scenario)
        return schedule_vec_env(cfg, len(holes), holes)

    def factory() -> gym.Env:
        if cfg.schedule:  # the same holes at every evaluation: fixed scenarios, each with its own seed
            return schedule_env(cfg, _schedule_eval_episodes(cfg, scenario))
        if cfg.eval_scenarios == "validation" and scenario is None:
            env: gym.Env = with_cell(gym.make(ENV_ID, **cfg.env_kwargs), cfg.training_cell())
            scenarios = validation_scenarios(cfg.eval_episodes, ranges=merged_ranges(cfg.dr_ranges))
            seeds = [episode_seed(Purpose.SELECT, VALIDATION_SEED + i) for i in range(len(scenarios))]
            env = ScenarioCycle(env, scenarios, seeds=seeds)
            return wrap_residual(env, cfg)
        return residual_env(cfg, False, scenario)

    return make_vec_env(factory, n_envs=1, seed=episode_seed(Purpose.SELECT, EVAL_SEED + cfg.seed))
