"""``drillgym tune-entry``: tune a slow entry on top of a base controller, on the paper and sweep suites.

A grid of entry feed multipliers × entry depths (:mod:`drillgym.controllers.feed_schedule`), and optionally × the
base's proportional gain (``--kps``: a slower entry changes how hard the base should push), is run on every
scenario of the tuning suites (default ``paper`` and ``sweep``, never ``heldout``, which stays for
judging learnt policies) over the same seeds as the base alone. The rule that picks the best schedule
is fixed before running:

* objective: the mean deviation, averaged over the suites (each suite's scenarios pooled, each suite
  weighing the same), lowest wins;
* constraints, each against the base on the same episodes: the peak lateral force of every suite not
  higher (pooled mean), and the drill time on the paper suite at most ``--max-time-increase`` longer.

Outputs in ``--out``: ``episodes.csv`` (every episode), ``grid.csv`` (one row per candidate),
``tune_entry.md`` and ``tune_entry.png`` (objective over the grid, the chosen cell marked).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

import pandas as pd

from drillgym.eval.bench.suites import SUITES
from drillgym.eval.calibration.cli import comma_floats

TUNING_SUITES = ("paper", "sweep")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--base", default="li2023", help="base controller spec (default li2023)")
    parser.add_argument(
        "--scales",
        type=comma_floats,
        default=[0.25, 0.35, 0.5, 0.7],
        help="entry feed multipliers (default %(default)s)",
    )
    parser.add_argument(
        "--depths-mm",
        type=comma_floats,
        default=[0.25, 0.5, 1.0, 1.5, 2.0],
        help="entry depths, mm (default %(default)s)",
    )
    parser.add_argument(
        "--kps",
        type=comma_floats,
        default=None,
        help="also tune the base's proportional gain kp over these values (default: keep the base's)",
    )
    parser.add_argument(
        "--y-gains",
        type=comma_floats,
        default=None,
        help="also tune li2023's y_gain (its correction across the plane of inclination) over these values "
        "(default: keep the base's)",
    )
    parser.add_argument("--suites", default=",".join(TUNING_SUITES), help="tuning suites (default paper,sweep)")
    parser.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 per scenario (default 5)")
    parser.add_argument(
        "--max-time-increase", type=float, default=0.3, help="allowed drill-time increase on paper (default 0.3)"
    )
    parser.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    parser.add_argument("--out", type=Path, default=Path("results/tune_entry"), help="output folder")


def gain_settings(kps: list[float] | None = None, y_gains: list[float] | None = None) -> list[str]:
    """The base's gain settings tried, as spec fields ending in a comma (kp-major order; ``[""]`` for none)."""
    kp_items = [f"kp={k:g}," for k in kps] if kps else [""]
    y_items = [f"y_gain={y:g}," for y in y_gains] if y_gains else [""]
    return [k + y for k in kp_items for y in y_items]


def candidate_specs(
    base: str,
    scales: list[float],
    depths_mm: list[float],
    kps: list[float] | None = None,
    y_gains: list[float] | None = None,
) -> list[str]:
    """The base alone, then the base with each (multiplier, depth) schedule, as controller specs.

    With ``kps`` and/or ``y_gains`` every schedule is tried at each of these gain settings (kp-major order).
    """
    sep = "," if ":" in base else ":"
    gains = gain_settings(kps, y_gains)
    return [base] + [
        f"{base}{sep}{g}entry_feed_scale={s:g},entry_depth_mm={d:g}" for g in gains for s in scales for d in depths_mm
    ]


def grid_table(episodes: pd.DataFrame, base: str, suites: list[str], max_time_increase: float) -> pd.DataFrame:
    """One row per candidate: per-suite pooled means, the objective, the constraints, ``feasible``."""
    per = episodes.groupby(["controller", "suite"])[["deviation_mean_mm", "lateral_force_max_n", "drill_time_s"]]
    means = per.mean()
    rows = []
    for spec in episodes["controller"].unique():
        row: dict[str, Any] = {"controller": spec}
        for suite in suites:
            for metric in ("deviation_mean_mm", "lateral_force_max_n", "drill_time_s"):
                row[f"{suite}_{metric}"] = float(means.loc[(spec, suite), metric])
        rows.append(row)
    grid = pd.DataFrame(rows).set_index("controller")
    grid["objective_mm"] = grid[[f"{s}_deviation_mean_mm" for s in suites]].mean(axis=1)
    ok = pd.Series(True, index=grid.index)
    reference: dict[Any, Any] = grid.loc[base].to_dict()
    for suite in suites:
        col = f"{suite}_lateral_force_max_n"
        ok &= grid[col] <= float(reference[col]) + 1e-12
    if "paper" in suites:
        ok &= grid["paper_drill_time_s"] <= (1.0 + max_time_increase) * float(reference["paper_drill_time_s"])
    grid["feasible"] = ok
    return grid.reset_index()


def best_candidate(grid: pd.DataFrame) -> str:
    """The feasible candidate with the lowest objective (the base itself is always a candidate)."""
    feasible = grid[grid["feasible"]]
    if feasible.empty:
        feasible = grid.iloc[:1]
    return str(feasible.sort_values("objective_mm").iloc[0]["controller"])


def check_arguments(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """The tuning suites and the candidate specs; bad arguments raise ``ValueError`` (the CLI's one-line error)."""
    from drillgym.controllers import make_controller

    suites = [s.strip() for s in args.suites.split(",") if s.strip()]
    unknown = [s for s in suites if s not in SUITES]
    if unknown or not suites:
        raise ValueError(f"unknown suite(s) {unknown}; choose from {', '.join(SUITES)}")
    if "heldout" in suites:
        raise ValueError("the heldout suite judges learnt policies; tune on paper and sweep only")
    if args.seeds < 1 or args.workers < 1:
        raise ValueError("--seeds and --workers must be >= 1")
    if args.kps and "kp=" in args.base:
        raise ValueError("--kps tunes the base's kp: leave kp out of --base")
    if args.y_gains and "y_gain=" in args.base:
        raise ValueError("--y-gains tunes the base's y_gain: leave y_gain out of --base")
    specs = candidate_specs(args.base, args.scales, args.depths_mm, args.kps, args.y_gains)
    for spec in specs:
        make_controller(spec)
    return suites, specs


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym tune-entry``."""
    from drillgym.eval.bench.episode import grid_jobs
    from drillgym.eval.bench.jobs import run_jobs
    from drillgym.eval.bench.report import episodes_frame

    suites, specs = check_arguments(args)
    rows = run_jobs(grid_jobs(suites, specs, args.seeds), args.workers, desc="tune-entry")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    episodes = episodes_frame(rows)
    episodes.to_csv(out / "episodes.csv", index=False)
    failed = episodes[episodes["error"].fillna("") != ""]
    if len(failed):
        print(f"drillgym tune-entry: {len(failed)} episodes failed; see episodes.csv", file=sys.stderr)
        return 1
    grid = grid_table(episodes, args.base, suites, args.max_time_increase)
    grid.to_csv(out / "grid.csv", index=False)
    best = best_candidate(grid)
    _write_markdown(out, grid, best, args)
    _plot(out / "tune_entry.png", grid, args, best)
    (out / "best.json").write_text(json.dumps({"best": best, "suites": suites, "seeds": args.seeds}, indent=2))
    print((out / "tune_entry.md").read_text())
    print(f"Results: {out.resolve()}/ (grid.csv, episodes.csv, tune_entry.md, tune_entry.png)")
    return 0


def _write_markdown(out: Path, grid: pd.DataFrame, best: str, args: argparse.Namespace) -> None:
    cols = [c for c in grid.columns if c != "controller"]
    lines = [
        f"# Slow-entry tuning on `{args.base}`",
        "",
        f"Suites {args.suites}, seeds 0..{args.seeds - 1}, the same episodes for every candidate"
        + (f", gains kp {args.kps}" if args.kps else "")
        + (f", y gains {args.y_gains}" if args.y_gains else "")
        + ". Objective: "
        "mean deviation averaged over the suites; feasible: peak lateral force not above the base's on any "
        f"suite and paper drill time at most +{args.max_time_increase:.0%}.",
        "",
        f"**Chosen: `{best}`**",
        "",
        "| controller | " + " | ".join(cols) + " |",
        "|---|" + "---|" * len(cols),
    ]
    for r in grid.sort_values("objective_mm").itertuples(index=False):
        values = [f"{v:.4g}" if isinstance(v, float) else str(v) for v in r[1:]]
        lines.append(f"| `{r[0]}` | " + " | ".join(values) + " |")
    (out / "tune_entry.md").write_text("\n".join(lines) + "\n")


def _plot(path: Path, grid: pd.DataFrame, args: argparse.Namespace, best: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    gains = [g.rstrip(",").replace(",", ", ") for g in gain_settings(args.kps, args.y_gains)]
    shape = (len(gains), len(args.scales), len(args.depths_mm))
    values = grid["objective_mm"].to_numpy()[1:].reshape(shape)
    feasible = grid["feasible"].to_numpy()[1:].reshape(shape)
    specs = grid["controller"].to_numpy()[1:].reshape(shape)
    ncols = min(len(gains), 4)
    nrows = -(-len(gains) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(6 * ncols, 4 * nrows), squeeze=False)
    for ax in axes.flat[len(gains) :]:
        ax.set_visible(False)
    lo, hi = float(np.nanmin(values)), float(np.nanmax(values))
    for g, ax in enumerate(axes.flat[: len(gains)]):
        im = ax.imshow(values[g], cmap="viridis_r", aspect="auto", vmin=lo, vmax=hi)
        for i in range(shape[1]):
            for j in range(shape[2]):
                text = f"{values[g, i, j]:.3f}" + ("" if feasible[g, i, j] else "\n(force/time)")
                color = "red" if specs[g, i, j] == best else "white"
                ax.text(j, i, text, ha="center", va="center", fontsize=7, color=color)
        ax.set_xticks(np.arange(shape[2]), [f"{d:g}" for d in args.depths_mm])
        ax.set_yticks(np.arange(shape[1]), [f"{s:g}" for s in args.scales])
        ax.set_xlabel("entry depth (mm)")
        ax.set_ylabel("entry feed multiplier (-)")
        if gains[g]:
            ax.set_title(gains[g], fontsize=9)
        fig.colorbar(im, ax=ax)
    base = float(grid["objective_mm"].iloc[0])
    fig.suptitle(f"mean deviation (mm) on {args.suites}; {args.base} alone: {base:.3f}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
