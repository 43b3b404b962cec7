"""Run a residual-training sweep on Ray Tune (ASHA) and export the best trial's policy.

Outputs in the sweep's folder ``OUT``:

* ``tune/``: Tune's experiment (one folder per trial: ``progress.csv``, ``result.json``, TensorBoard
  files, ``eval/curve.csv`` and the best checkpoints ``checkpoint_NNNNNN/``);
* ``trials.csv``: one row per trial (its hyperparameters, evaluations, best and last deviation, status);
* ``policy.zip`` + ``policy.vecnormalize.pkl`` + ``policy.json``: the checkpoint with the lowest
  evaluation deviation of any trial, a policy bundle like ``drillgym train`` writes;
* ``sweep.json``: the sweep, the best trial and the timings.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from ray import tune
from ray.tune.schedulers import ASHAScheduler
from ray.tune.search import BasicVariantGenerator

from drillgym.eval.scale.cluster import ray_session
from drillgym.eval.scale.tune_trial import METRIC, TIME_ATTR, train_trial
from drillgym.training.config import TrainConfig
from drillgym.training.policy_bundle import save_bundle
from drillgym.training.sweep import SweepSpec

TRIAL_COLUMNS = ("trial_id", "status", "evaluations", TIME_ATTR, "best_" + METRIC, "last_" + METRIC)
"""Leading columns of ``trials.csv`` (the searched hyperparameters follow)."""


@dataclass
class SweepOutcome:
    """What a sweep returns."""

    trials: pd.DataFrame
    best: dict[str, Any] | None
    """The best trial: ``trial_id``, ``config``, ``METRIC``, ``timesteps``; None when no trial reported."""
    startup_s: float
    """Ray start-up (s)."""
    tune_s: float
    """``Tuner.fit`` (s)."""


def param_space(spec: SweepSpec) -> dict[str, Any]:
    """Tune's search space: the base configuration with every searched field replaced by its sampler."""
    space: dict[str, Any] = spec.base.to_dict()
    for name, (kind, args) in spec.search.items():
        if kind == "choice":
            space[name] = tune.choice(args)
        elif kind == "grid":
            space[name] = tune.grid_search(args)
        elif kind == "uniform":
            space[name] = tune.uniform(*args)
        elif kind == "loguniform":
            space[name] = tune.loguniform(*args)
        else:
            space[name] = tune.randint(int(args[0]), int(args[1]))
    return space


def _dirname(trial: Any) -> str:
    return f"trial_{trial.trial_id}"


def build_tuner(spec: SweepSpec, out: Path) -> tune.Tuner:
    """The Tuner: trials of :func:`train_trial`, ASHA on :data:`METRIC`, checkpoints kept by score."""
    scheduler = ASHAScheduler(
        time_attr=TIME_ATTR,
        max_t=spec.base.total_timesteps,
        grace_period=spec.grace_period,
        reduction_factor=spec.reduction_factor,
    )
    return tune.Tuner(
        tune.with_resources(train_trial, {"cpu": spec.cpus_per_trial}),
        param_space=param_space(spec),
        tune_config=tune.TuneConfig(
            metric=METRIC,
            mode="min",
            scheduler=scheduler,
            search_alg=BasicVariantGenerator(random_state=spec.seed),
            num_samples=spec.samples,
            max_concurrent_trials=spec.max_concurrent_trials,
            trial_dirname_creator=_dirname,
        ),
        run_config=tune.RunConfig(
            name="tune",
            storage_path=str(Path(out).resolve()),
            checkpoint_config=tune.CheckpointConfig(
                num_to_keep=2, checkpoint_score_attribute=METRIC, checkpoint_score_order="min"
            ),
            failure_config=tune.FailureConfig(max_failures=spec.max_failures),
            verbose=1,
        ),
    )


def trials_frame(results: tune.ResultGrid, spec: SweepSpec) -> pd.DataFrame:
    """One row per trial: status ``finished``, ``stopped early`` (by ASHA) or ``error``, and its results."""
    rows = []
    for result in (results[i] for i in range(len(results))):
        history = result.metrics_dataframe
        if history is None or METRIC not in history:
            history = pd.DataFrame({METRIC: [], TIME_ATTR: []})
        evaluations = len(history)
        if result.error is not None:
            status = "error"
        else:
            status = "finished" if evaluations >= spec.evaluations else "stopped early"
        config = dict(result.config or {})
        rows.append(
            {
                "trial_id": Path(result.path).name.removeprefix("trial_"),
                "status": status,
                "evaluations": evaluations,
                TIME_ATTR: int(history[TIME_ATTR].max()) if evaluations else 0,
                "best_" + METRIC: float(history[METRIC].min()) if evaluations else float("nan"),
                "last_" + METRIC: float(history[METRIC].iloc[-1]) if evaluations else float("nan"),
                **{k: config.get(k) for k in spec.search},
            }
        )
    return pd.DataFrame(rows).sort_values("best_" + METRIC, na_position="last").reset_index(drop=True)


def export_best(results: tune.ResultGrid, out: Path, spec: SweepSpec, extra: list[Path]) -> dict[str, Any] | None:
    """Save the best checkpoint of the best trial as ``out/policy.zip`` (and every path in ``extra``)."""
    try:
        best = results.get_best_result(METRIC, "min", scope="all")
    except RuntimeError:
        return None
    checkpoint = best.get_best_checkpoint(METRIC, "min")
    if checkpoint is None:
        return None
    history, config = best.metrics_dataframe, dict(best.config or {})
    if history is None or METRIC not in history:
        return None
    row = history.iloc[int(history[METRIC].to_numpy().argmin())].to_dict()
    info = {
        "trial_id": Path(best.path).name.removeprefix("trial_"),
        METRIC: float(row[METRIC]),
        TIME_ATTR: int(row[TIME_ATTR]),
        "base_deviation_mm": float(row.get("base_deviation_mm", float("nan"))),
        "config": {k: config[k] for k in spec.search},
        "trial_path": str(best.path),
    }
    cfg = TrainConfig(**config)
    meta = {"sweep": {"name": spec.name, "best": info}}
    with checkpoint.as_directory() as folder:
        for dest in [out / "policy.zip", *extra]:
            save_bundle(Path(folder) / "model.zip", Path(folder) / "vecnormalize.pkl", cfg, meta, dest)
    return info


def run_sweep(spec: SweepSpec, out: Path, address: str | None = None, export: Path | None = None) -> SweepOutcome:
    """Run the sweep on Ray (local unless ``address``), write the outputs, print the trials."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with ray_session(address) as session:
        print(session.describe())
        t0 = time.perf_counter()
        results = build_tuner(spec, out).fit()
        tune_s = time.perf_counter() - t0
    trials = trials_frame(results, spec)
    trials.to_csv(out / "trials.csv", index=False)
    best = export_best(results, out, spec, [export] if export is not None else [])
    summary = {
        "sweep": spec.name,
        "base": spec.base.to_dict(),
        "search": {k: {kind: args} for k, (kind, args) in spec.search.items()},
        "trials": len(trials),
        "stopped_early": int((trials["status"] == "stopped early").sum()),
        "errors": int((trials["status"] == "error").sum()),
        "best": best,
        "ray_startup_s": session.startup_s,
        "tune_s": tune_s,
    }
    (out / "sweep.json").write_text(json.dumps(summary, indent=2, default=str))
    with pd.option_context("display.width", 160, "display.max_columns", 20):
        print(trials.to_string(index=False))
    n_stopped, n = summary["stopped_early"], len(trials)
    print(
        f"sweep {spec.name}: {n} trials, {n_stopped} stopped early by ASHA, {summary['errors']} failed, {tune_s:.0f} s"
    )
    if best is None:
        print("no trial reported an evaluation: no policy exported")
    else:
        print(f"best: trial {best['trial_id']} {METRIC} {best[METRIC]:.3f} mm at {best[TIME_ATTR]} steps")
        print(f"policy: {(out / 'policy.zip').resolve()}")
    return SweepOutcome(trials, best, session.startup_s, tune_s)
