"""Simulate Li's runs with one candidate at one parameter value: the paper scenario over seeds.

The cell keeps its shipped calibration; the candidate's effect (if any) is switched on for every run.
li2023's force model is refitted to this cell's own uncompensated F/T force (seed of the first run), as Li
fitted his to his own trial hole, then the candidate's controller overrides are applied. The other seeds run
together on the batched engine where the candidate's effect is compiled (the same rows as one by one on the
single env, bit for bit: :func:`drillgym.controllers.rollout.run_episodes`).
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers.registry import make_controller
from drillgym.controllers.rollout import run_episode, run_episodes
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.effects import build_effects
from drillgym.envs.effects.registry import runs_compiled
from drillgym.envs.errors import UserError
from drillgym.eval.calibration.calibrate import fit_controller_model_n
from drillgym.eval.explain.candidates import Candidate
from drillgym.eval.explain.observations import METRICS

RUN_OVERRIDES = {"kp1": {"kp": 1.0}, "kp4": {"kp": 4.0}}
"""li2023 gains of Li's compensated runs."""

_ENV: dict[str, Any] = {}


def _env() -> Any:
    if "env" not in _ENV:
        _ENV["env"] = gym.make(SIM_ENV_ID)
    return _ENV["env"]


def close() -> None:
    """Close this process's env."""
    env = _ENV.pop("env", None)
    if env is not None:
        env.close()


def simulate(candidate: Candidate | None, value: float, runs: tuple[str, ...], seeds: list[int]) -> dict[str, Any]:
    """Per-seed metrics of each run in ``runs`` (``none``, ``kp1``, ``kp4``) with the candidate at ``value``.

    Returns:
        ``{run: {metric: [value per seed]}}`` plus ``"model_peak_n"`` (li2023's fitted model peak, N).
        ``candidate=None`` is the nominal cell.
    """
    if not seeds:
        raise UserError("at least one seed is needed")
    env = _env()
    spec = candidate.effects_spec(value) if candidate else ""
    env.unwrapped.set_effects(build_effects(spec) if spec else None)
    try:
        first = run_episode(env, None, seed=seeds[0])
        peak = fit_controller_model_n(env, first.trace)
        out: dict[str, Any] = {"model_peak_n": peak}
        batched = runs_compiled(spec)
        for run in runs:
            if run == "none":
                rest = _rows(env, "none", seeds[1:], spec, batched)
                rows = [first.metrics, *rest]
            else:
                overrides = dict(RUN_OVERRIDES[run])
                overrides.update(
                    candidate.controller_overrides(value, peak) if candidate else {"model_peak_force_n": peak}
                )
                ctrl = "li2023:" + ",".join(f"{k}={v!r}" for k, v in overrides.items())
                rows = _rows(env, ctrl, seeds, spec, batched)
            out[run] = {k: [float(r[k]) for r in rows] for k in METRICS}
    finally:
        env.unwrapped.set_effects(None)
    return out


def _rows(env: Any, ctrl: str, seeds: list[int], spec: str, batched: bool) -> list[dict[str, Any]]:
    """Metric rows of ``ctrl`` on ``seeds`` in the cell of effects ``spec``: all at once where it is compiled."""
    if not seeds:
        return []
    if batched:
        return [r.row() for r in run_episodes(functools.partial(make_controller, ctrl), seeds, {}, spec)]
    return [run_episode(env, make_controller(ctrl), s, keep_trace=False).row() for s in seeds]


def means(result: dict[str, Any]) -> dict[str, dict[str, float]]:
    """``{run: {metric: mean over seeds}}`` of a :func:`simulate` result."""
    return {run: {k: float(np.mean(v)) for k, v in m.items()} for run, m in result.items() if run != "model_peak_n"}
