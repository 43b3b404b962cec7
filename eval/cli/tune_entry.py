"""``drillgym tune-entry``: tune a slow entry on top of a controller on the paper and sweep suites (:mod:`drillgym.eval.bench.tune_entry`)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from drillgym.envs.errors import UserError
from drillgym.eval.bench.suites import JUDGE_ONLY_SUITES, SUITES
from drillgym.eval.bench.tune_entry import TUNING_SUITES, best_candidate, candidate_specs, gain_settings, grid_table
from drillgym.eval.cli.bench import refuse_previous_record
from drillgym.eval.cli.calibrate import comma_floats


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
    parser.add_argument(
        "--seeds",
        type=int,
        default=5,
        help="tuning episodes per scenario (default 5): episodes 0..N-1 of the tuning seed namespace, never a judge episode (drillgym.envs.seeds)",
    )
    parser.add_argument(
        "--max-time-increase", type=float, default=0.3, help="allowed drill-time increase on paper (default 0.3)"
    )
    parser.add_argument("--workers", type=int, default=1, help="parallel worker processes (default 1)")
    parser.add_argument("--out", type=Path, default=Path("results/tune_entry"), help="output folder")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace a previous record in --out (without it, one is refused)"
    )


RECORD_FILES = ("episodes.csv", "grid.csv", "best.json", "tune_entry.md", "tune_entry.png")
"""What a tune-entry run writes into its --out."""


def check_arguments(args: argparse.Namespace) -> tuple[list[str], list[str]]:
    """The tuning suites and the candidate specs; bad arguments raise ``ValueError`` (the CLI's one-line error)."""
    from drillgym.controllers import make_controller

    suites = [s.strip() for s in args.suites.split(",") if s.strip()]
    unknown = [s for s in suites if s not in SUITES]
    if unknown or not suites:
        raise UserError(f"unknown suite(s) {unknown}; choose from {', '.join(SUITES)}")
    judged = [s for s in suites if s in JUDGE_ONLY_SUITES]
    if judged:
        raise UserError(
            f"the {' and '.join(judged)} suite(s) judge tuned and learnt controllers; tune on paper and sweep only"
        )
    if args.seeds < 1 or args.workers < 1:
        raise UserError("--seeds and --workers must be >= 1")
    if args.kps and "kp=" in args.base:
        raise UserError("--kps tunes the base's kp: leave kp out of --base")
    if args.y_gains and "y_gain=" in args.base:
        raise UserError("--y-gains tunes the base's y_gain: leave y_gain out of --base")
    specs = candidate_specs(args.base, args.scales, args.depths_mm, args.kps, args.y_gains)
    for spec in specs:
        make_controller(spec)
    refuse_previous_record(args.out, RECORD_FILES, args.overwrite, "tune-entry record")
    return suites, specs


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym tune-entry``."""
    from drillgym.envs.seeds import Purpose
    from drillgym.eval.bench.episode import grid_jobs
    from drillgym.eval.bench.jobs import run_jobs
    from drillgym.eval.bench.report import episodes_frame

    suites, specs = check_arguments(args)
    rows = run_jobs(grid_jobs(suites, specs, args.seeds, Purpose.TUNE), args.workers, desc="tune-entry")
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
        f"Suites {args.suites}, tuning episodes 0..{args.seeds - 1} (seed namespace `tune`), the same episodes for every candidate"
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
