"""``drillgym demo``: the paper scenario end to end, metrics against Li et al. 2023, results on disk."""

from __future__ import annotations

import argparse
import csv
import json
import statistics
from pathlib import Path
from typing import Any

from tqdm import tqdm

from eval.paper import CALIBRATION_TOLERANCE, LI2023_UNCOMPENSATED


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", type=Path, default=Path("results/demo"), help="output folder (default results/demo)")
    parser.add_argument("--seeds", type=int, default=5, help="episodes (seeds 0..N-1; default 5)")


def run(args: argparse.Namespace) -> int:
    """Run the uncompensated paper scenario over seeds, print the comparison, write CSV/JSON/PNG."""
    import gymnasium as gym

    from eval.plots import plot_episode
    from eval.rollout import run_episode

    if args.seeds < 1:
        raise SystemExit(f"--seeds={args.seeds} must be >= 1")
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    env = gym.make("drillgym/UR5BoneDrill-v0")
    results = [run_episode(env, None, seed) for seed in tqdm(range(args.seeds), desc="paper scenario", unit="ep")]
    env.close()
    names = list(results[0].metrics)
    with open(out / "paper_uncompensated.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["seed", *names])
        for r in results:
            w.writerow([r.seed, *(f"{r.metrics[n]:.6g}" for n in names)])
    summary: dict[str, Any] = {"scenario": "paper (beta 30 deg, 0.5 mm/s, 20000 rpm, 1.5 mm)", "controller": "none"}
    rows = []
    for n in names:
        vals = [r.metrics[n] for r in results]
        mean = statistics.fmean(vals)
        sd = statistics.stdev(vals) if len(vals) > 1 else 0.0
        paper = LI2023_UNCOMPENSATED.get(n)
        rel = (mean - paper) / paper if paper else None
        summary[n] = {"mean": mean, "sd": sd, "paper": paper, "rel_err": rel}
        rows.append((n, paper, mean, sd, rel))
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    plot_episode(results[0], out / "paper_uncompensated.png", title="Paper scenario, no compensation (seed 0)")
    print(f"\nUncompensated paper scenario (beta 30 deg, 0.5 mm/s), {len(results)} seeds:\n")
    print(f"  {'metric':26s} {'paper':>8s} {'sim mean':>9s} {'sd':>7s} {'rel. err':>9s}")
    for n, paper, mean, sd, rel in rows:
        p = f"{paper:8.3f}" if paper is not None else f"{'-':>8s}"
        e = f"{rel:+8.1%}" if rel is not None else f"{'':>8s}"
        tol = CALIBRATION_TOLERANCE.get(n)
        flag = "" if tol is None or rel is None else ("  ok" if abs(rel) <= tol else f"  outside ±{tol:.0%}")
        print(f"  {n:26s} {p} {mean:9.3f} {sd:7.3f} {e}{flag}")
    print(f"\nResults: {out.resolve()}/ (paper_uncompensated.csv, summary.json, paper_uncompensated.png)")
    return 0
