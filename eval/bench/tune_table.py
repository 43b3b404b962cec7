"""Tune a gain-scheduling table (:mod:`drillgym.controllers.schedule_table`) on tuning episodes only.

The command is :mod:`drillgym.eval.cli.tune_table`. It is the classical tuner a learnt schedule is judged
against: it moves the same fields as the schedule residual (KP, y gain, entry feed scale, entry depth of
``li2023_tuned``, within the same spans) and optimises the same paired reward
(:func:`drillgym.training.schedule_env.paired_schedule_reward`: the benchmark's acceptance in one number,
against ``li2023_tuned`` drilling the same specimen).

The rule, fixed before any run:

* **anchors** (:func:`anchor_scenarios`): the nominal plan (the paper scenario), each numeric plan feature at
  both ends of its training range (the rest nominal), and each other training bone: 11 anchors;
* **episodes**: ``seeds`` tuning episodes per anchor (:attr:`drillgym.envs.seeds.Purpose.TUNE`: never a judge
  specimen), the same for every candidate; ``li2023_tuned``'s own episodes are drilled once per anchor;
* **optimiser**: SciPy's Nelder–Mead per anchor from ``a = 0`` (``li2023_tuned`` itself), inside [-1, 1] per
  field, an initial simplex of ``step`` along each field, at most ``evals`` candidates per anchor: the hole
  budget is ``anchors × seeds × (evals + 1)``;
* **choice**: each anchor keeps its best candidate by the mean paired reward; a candidate that does not beat
  0 (the base) leaves the anchor at ``a = 0``.

Outputs in ``--out``: ``table.json`` (the table), ``evaluations.csv`` (every candidate of every anchor),
``tune_table.md``, ``tune_table.png`` (each anchor's best reward against the evaluations spent).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import minimize

from drillgym.controllers import make_controller
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec, normalized_plan
from drillgym.controllers.rollout import run_episodes
from drillgym.controllers.schedule_table import Anchor, ScheduleTable
from drillgym.envs.errors import UserError
from drillgym.envs.scenario import Scenario
from drillgym.envs.seeds import Purpose, episode_seed
from drillgym.training.domain_randomization import TRAINING_BONES, TRAINING_RANGES, training_plan_support
from drillgym.training.schedule_env import ScheduleReward, paired_schedule_reward

DEFAULT_BASE = "li2023_tuned"


@dataclass(frozen=True)
class AnchorJob:
    """One anchor to tune (what a worker process receives)."""

    name: str
    scenario: dict[str, Any]
    spec: ScheduleSpec
    seeds: tuple[int, ...]
    evals: int
    step: float
    reward: ScheduleReward


def anchor_scenarios(
    ranges: dict[str, tuple[float, float]] = TRAINING_RANGES, bones: tuple[str, ...] = TRAINING_BONES
) -> list[tuple[str, dict[str, Any]]]:
    """``(name, scenario arguments)`` of the anchors: nominal, each range's ends, each other bone."""
    nominal = Scenario()
    out: list[tuple[str, dict[str, Any]]] = [("nominal", {})]
    for name, (lo, hi) in ranges.items():
        out += [(f"{name}={v:g}", {name: float(v)}) for v in (lo, hi) if not math.isclose(v, getattr(nominal, name))]
    out += [(f"bone={b}", {"bone": b}) for b in bones if b != nominal.bone]
    return out


def tuning_seeds(seeds: int, offset: int = 0) -> tuple[int, ...]:
    """Episodes ``offset .. offset + seeds - 1`` of the tuning namespace (:mod:`drillgym.envs.seeds`)."""
    return tuple(episode_seed(Purpose.TUNE, offset + i) for i in range(seeds))


def tune_anchor(job: AnchorJob) -> dict[str, Any]:
    """Nelder–Mead on one anchor: its best action and every evaluation (a worker's job).

    Returns:
        ``{"name", "action", "reward", "chosen", "evaluations": [{"eval", "action", "reward", "deviation_mm",
        "force_n", "time_s"}, ...], "base": {deviation_mm, force_n, time_s}}``; ``chosen`` is the kept candidate's
        evaluation (the base's, ``a = 0``, when none beat it).
    """
    seeds = list(job.seeds)  # every evaluation drills them together on the batched engine (run_episodes)
    base = [r.metrics for r in run_episodes(lambda: make_controller(job.spec.base), seeds, job.scenario)]
    evaluations: list[dict[str, Any]] = []
    cache: dict[tuple[float, ...], float] = {}

    def objective(x: np.ndarray) -> float:
        a = np.clip(np.asarray(x, dtype=np.float64), -1.0, 1.0)
        key = tuple(np.round(a, 12))
        if key in cache:
            return cache[key]
        make = functools.partial(PlanScheduledController, job.spec, policy=lambda _obs: a)
        rows = [r.metrics for r in run_episodes(make, seeds, job.scenario)]
        rewards = [paired_schedule_reward(r, b, job.reward) for r, b in zip(rows, base, strict=True)]
        value = float(np.mean(rewards))
        evaluations.append(
            {
                "eval": len(evaluations),
                "action": [float(v) for v in a],
                "reward": value,
                "deviation_mm": float(np.mean([r["deviation_mean_mm"] for r in rows])),
                "force_n": float(np.mean([r["lateral_force_max_n"] for r in rows])),
                "time_s": float(np.mean([r["drill_time_s"] for r in rows])),
            }
        )
        cache[key] = -value
        return -value

    dims = job.spec.dims
    x0 = np.zeros(dims)
    simplex = np.vstack([x0, *(x0 + job.step * np.eye(dims)[i] for i in range(dims))])
    objective(x0)  # the base itself (reward 0 by construction) is the first candidate
    minimize(
        objective,
        x0,
        method="Nelder-Mead",
        bounds=[(-1.0, 1.0)] * dims,
        options={"maxfev": job.evals, "initial_simplex": simplex, "xatol": 0.01, "fatol": 1e-5},
    )
    best = max(evaluations, key=lambda e: e["reward"])
    chosen = best if best["reward"] > 0.0 else evaluations[0]  # evaluations[0] is the base, a = 0
    return {
        "name": job.name,
        "action": chosen["action"],
        "reward": chosen["reward"],
        "chosen": chosen,
        "evaluations": evaluations,
        "base": {
            "deviation_mm": float(np.mean([b["deviation_mean_mm"] for b in base])),
            "force_n": float(np.mean([b["lateral_force_max_n"] for b in base])),
            "time_s": float(np.mean([b["drill_time_s"] for b in base])),
        },
    }


def anchor_jobs(
    base: str = DEFAULT_BASE, seeds: int = 8, evals: int = 30, step: float = 0.3, seed_offset: int = 0
) -> list[AnchorJob]:
    """The tuning jobs, one per anchor, with the schedule residual's fields, spans and plan support."""
    if seeds < 2 or evals < 2 or not 0.0 < step <= 1.0 or seed_offset < 0:
        raise UserError(
            f"need seeds >= 2, evals >= 2, 0 < step <= 1, seed offset >= 0; got {seeds}, {evals}, {step}, {seed_offset}"
        )
    spec = ScheduleSpec(base=base, plan_support=training_plan_support())
    episode_seeds = tuning_seeds(seeds, seed_offset)
    return [
        AnchorJob(name, scenario, spec, episode_seeds, evals, step, ScheduleReward())
        for name, scenario in anchor_scenarios()
    ]


def build_table(jobs: list[AnchorJob], results: list[dict[str, Any]], meta: dict[str, Any]) -> ScheduleTable:
    """The table of tuned anchors (``results`` in the order of ``jobs``)."""
    spec = jobs[0].spec
    anchors = tuple(
        Anchor(
            job.name,
            job.scenario,
            tuple(float(v) for v in normalized_plan(Scenario.from_kwargs(**job.scenario), spec.plan_support)),
            tuple(float(v) for v in res["action"]),
        )
        for job, res in zip(jobs, results, strict=True)
    )
    return ScheduleTable(spec, anchors, meta)
