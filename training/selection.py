"""Pick a run's policy among its saved models by what the benchmark judges, on the validation episodes.

SB3's ``EvalCallback`` keeps the model with the best mean validation *reward*. The reward sums per-step
penalties, so it also charges a policy for every extra step it drills: a policy that lowers the mean
deviation by slowing the feed can score a lower reward than the base. ``model_selection: deviation``
instead scores every saved model (each checkpoint, the final model and the best-reward model) on the
same validation episodes as the training's evaluations (:func:`drillgym.training.domain_randomization.validation_scenarios`,
fixed seeds; never the heldout suite) together with the base controller, and picks by a rule fixed in
advance, which mirrors the benchmark's acceptance:

* feasible: the peak lateral force not significantly above the base's (paired 95 % CI's low end ≤ 0) and
  the drill time at most :data:`MAX_TIME_RATIO` times the base's;
* better: the mean deviation significantly below the base's (paired 95 % CI's high end < 0);
* chosen: the feasible and better model with the lowest mean deviation; if there is none, the feasible
  model with the lowest mean deviation, and if no model is feasible, the final one; ``selection.json``
  says which rule chose.

The choice depends only on the saved models and these episodes, not on the evaluations made while
training.

Every candidate's figures go to ``selection.csv``. The evaluation is deterministic, so a run's selection
is reproduced from its files.
"""

from __future__ import annotations

import csv
import functools
import json
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from scipy import special

from drillgym.controllers import Controller, make_controller
from drillgym.controllers.rollout import run_batch, run_episode
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.seeds import Purpose, episode_seed
from drillgym.training.cell import with_cell
from drillgym.training.config import TrainConfig
from drillgym.training.domain_randomization import VALIDATION_SEED, ScenarioCycle, merged_ranges, validation_scenarios

ENV_ID = SIM_ENV_ID
MAX_TIME_RATIO = 1.3
"""A candidate may drill at most this much longer than the base on the validation episodes (mean)."""
CONFIDENCE = 0.95


@dataclass
class Candidate:
    """A saved model of a run: its name, SB3 zip and observation normaliser."""

    name: str
    model_zip: Path
    normalizer: Path | None


def candidates(run: Path) -> list[Candidate]:
    """Every checkpoint (in step order) and the final model of a run folder."""
    found: list[tuple[int, Candidate]] = []
    for p in (run / "checkpoints").glob("rl_model_*_steps.zip"):
        m = re.fullmatch(r"rl_model_(\d+)_steps\.zip", p.name)
        if m:
            norm = run / "checkpoints" / f"rl_model_vecnormalize_{m.group(1)}_steps.pkl"
            found.append((int(m.group(1)), Candidate(f"checkpoint_{m.group(1)}", p, norm if norm.exists() else None)))
    out = [c for _, c in sorted(found, key=lambda x: x[0])]
    model, norm = run / "model.zip", run / "vecnormalize.pkl"
    if model.exists():
        out.append(Candidate("final", model, norm if norm.exists() else None))
    return out


PAPER_SELECTION_SEED = VALIDATION_SEED + 100_000
"""Index of the first extra paper-scenario selection episode in the selection namespace."""


def validation_episodes(cfg: TrainConfig) -> list[tuple[dict[str, Any], int]]:
    """The (scenario, seed) pairs of the training's evaluations, plus ``cfg.selection_paper_episodes`` paper ones.

    Their seeds lie in the selection namespace (:mod:`drillgym.envs.seeds`): never a judge or training episode.
    """
    scenarios = validation_scenarios(cfg.eval_episodes, ranges=merged_ranges(cfg.dr_ranges))
    episodes = [(sc, episode_seed(Purpose.SELECT, VALIDATION_SEED + i)) for i, sc in enumerate(scenarios)]
    paper: list[tuple[dict[str, Any], int]] = [
        ({}, episode_seed(Purpose.SELECT, PAPER_SELECTION_SEED + i)) for i in range(cfg.selection_paper_episodes)
    ]
    return episodes + paper


def score(
    make: Callable[[], Controller], cfg: TrainConfig, episodes: list[tuple[dict[str, Any], int]]
) -> dict[str, list]:
    """Deviation (mm), peak lateral force (N) and drill time (s) of each validation episode, a controller from ``make``.

    On the batched engine (one copy per episode, all in one batch), but where the cell has effects the compiled step
    does not run: those run one after another on the single env. The same numbers either way.
    """
    out: dict[str, list] = {"deviation_mean_mm": [], "lateral_force_max_n": [], "drill_time_s": []}
    scenarios, seeds = [sc for sc, _ in episodes], [seed for _, seed in episodes]
    cell = cfg.training_cell()
    if cell.compiled:
        batch = BatchedDrillEnv(len(episodes), autoreset=False, effects=cell.nominal_spec(), **cfg.env_kwargs)
        try:  # a fresh batch: each listed scenario changes the env's own, as ScenarioCycle's
            results = run_batch(batch, [make() for _ in episodes], seeds, scenarios)
        finally:
            batch.close()
    else:
        env = ScenarioCycle(with_cell(gym.make(ENV_ID, **cfg.env_kwargs), cell), scenarios, seeds)
        controller = make()
        try:  # the cycle seeds each episode
            results = [run_episode(env, controller, seed=None, keep_trace=False) for _ in episodes]
        finally:
            env.close()
    for result in results:
        for key, values in out.items():
            values.append(float(result.metrics[key]))
    return out


def _paired(a: list[float], b: list[float]) -> tuple[float, float, float]:
    d = np.asarray(a) - np.asarray(b)
    half = special.stdtrit(len(d) - 1, 0.5 + CONFIDENCE / 2) * d.std(ddof=1) / math.sqrt(len(d))  # = stats.t.ppf
    return float(d.mean()), float(d.mean() - half), float(d.mean() + half)


def judge(policy: dict[str, list], base: dict[str, list]) -> dict[str, Any]:
    """One candidate's figures against the base, and whether it is feasible and better (the rule above)."""
    dev, dev_lo, dev_hi = _paired(policy["deviation_mean_mm"], base["deviation_mean_mm"])
    force, force_lo, force_hi = _paired(policy["lateral_force_max_n"], base["lateral_force_max_n"])
    time_ratio = float(np.mean(policy["drill_time_s"]) / np.mean(base["drill_time_s"]))
    return {
        "deviation_mean_mm": float(np.mean(policy["deviation_mean_mm"])),
        "lateral_force_max_n": float(np.mean(policy["lateral_force_max_n"])),
        "drill_time_s": float(np.mean(policy["drill_time_s"])),
        "d_deviation_mm": dev,
        "d_deviation_low": dev_lo,
        "d_deviation_high": dev_hi,
        "d_force_n": force,
        "d_force_low": force_lo,
        "d_force_high": force_hi,
        "time_ratio": time_ratio,
        "feasible": bool(force_lo <= 0.0 and time_ratio <= MAX_TIME_RATIO),
        "better": bool(dev_hi < 0.0),
    }


def choose(rows: list[dict[str, Any]]) -> tuple[str, str]:
    """The chosen candidate's name and the rule that chose it, from :func:`judge`'s rows (see the module)."""
    eligible = [r for r in rows if r["feasible"] and r["better"]]
    feasible = [r for r in rows if r["feasible"]]
    if eligible:
        return min(eligible, key=lambda r: r["deviation_mean_mm"])["candidate"], "lowest deviation, beats the base"
    if feasible:
        best = min(feasible, key=lambda r: r["deviation_mean_mm"])["candidate"]
        return best, "no saved model beat the base on validation: the feasible one with the lowest deviation"
    return "final", "no saved model kept the base's force and time: the final model"


def select(run: Path, cfg: TrainConfig, progress: bool = True) -> dict[str, Any]:
    """Score every saved model of ``run`` and the base; write ``selection.csv`` and ``selection.json``.

    Returns the selection (``chosen``: the candidate's name, ``rule``: which rule chose it).
    """
    from drillgym.training.policy_bundle import save_bundle
    from drillgym.training.residual_policy import load_residual_controller

    episodes = validation_episodes(cfg)
    base = score(lambda: make_controller(cfg.base), cfg, episodes)
    rows: list[dict[str, Any]] = []
    folder = run / "candidates"
    for cand in candidates(run):
        bundle = folder / f"{cand.name}.zip"
        save_bundle(cand.model_zip, cand.normalizer, cfg, {"candidate": cand.name}, bundle)
        row = {
            "candidate": cand.name,
            **judge(score(functools.partial(load_residual_controller, bundle), cfg, episodes), base),
        }
        rows.append(row)
        if progress:
            print(
                f"  {cand.name}: deviation {row['deviation_mean_mm']:.4f} mm ({row['d_deviation_mm']:+.4f}), "
                f"peak {row['lateral_force_max_n']:.3f} N ({row['d_force_n']:+.3f}), time x{row['time_ratio']:.2f}",
                flush=True,
            )
    if not rows:
        raise FileNotFoundError(f"{run} holds no saved model (checkpoints/ or model.zip) to select from")
    chosen, rule = choose(rows)
    base_row = {k: float(np.mean(v)) for k, v in base.items()}
    result = {"chosen": chosen, "rule": rule, "base": base_row, "episodes": len(episodes), "candidates": rows}
    with open(run / "selection.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    (run / "selection.json").write_text(json.dumps(result, indent=2))
    return result


def chosen_model(run: Path, selection: dict[str, Any]) -> tuple[Path, Path | None]:
    """The SB3 zip and normaliser of the chosen candidate."""
    for cand in candidates(run):
        if cand.name == selection["chosen"]:
            return cand.model_zip, cand.normalizer
    raise FileNotFoundError(f"{run}: the chosen model {selection['chosen']!r} is not among its saved models")
