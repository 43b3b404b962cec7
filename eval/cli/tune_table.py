"""``drillgym tune-table``: tune a gain-scheduling table on tuning episodes (:mod:`drillgym.eval.bench.tune_table`)."""

from __future__ import annotations

import argparse
import json
import platform
import shlex
import time
from pathlib import Path

from drillgym.envs.errors import UserError
from drillgym.eval.bench.tune_table import DEFAULT_BASE


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--base", default=DEFAULT_BASE, help=f"base controller spec (default {DEFAULT_BASE})")
    parser.add_argument(
        "--seeds",
        type=int,
        default=8,
        help="tuning episodes per anchor (default 8): episodes of the tuning seed namespace, never a judge episode",
    )
    parser.add_argument(
        "--seed-offset", type=int, default=0, help="first tuning episode index (default 0; another draw of episodes)"
    )
    parser.add_argument("--evals", type=int, default=30, help="candidates per anchor, the base included (default 30)")
    parser.add_argument("--step", type=float, default=0.3, help="Nelder–Mead's initial step per field (default 0.3)")
    parser.add_argument("--workers", type=int, default=1, help="parallel worker processes, one anchor each (default 1)")
    parser.add_argument("--out", type=Path, default=Path("results/tune_table"), help="output folder (must be new)")


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym tune-table``."""
    from drillgym.eval.bench.tune_table import anchor_jobs, build_table, tune_anchor
    from drillgym.eval.bench.tune_table_report import write_report
    from drillgym.eval.pool import run_unordered

    out: Path = args.out
    if (out / "table.json").exists():
        raise FileExistsError(f"{out}/table.json exists: a tuned table is never overwritten; choose another --out")
    if args.workers < 1:
        raise UserError("--workers must be >= 1")
    jobs = anchor_jobs(args.base, args.seeds, args.evals, args.step, args.seed_offset)
    budget = len(jobs) * args.seeds * (args.evals + 1)
    print(
        f"tune-table: {len(jobs)} anchors × {args.seeds} tuning episodes × ≤ {args.evals} candidates (+ base): ≤ {budget} holes"
    )
    from tqdm import tqdm

    t0 = time.perf_counter()
    results: list[dict | None] = [None] * len(jobs)
    with tqdm(total=len(jobs), desc="tune-table anchors", unit="anchor") as bar:
        for i, result in run_unordered(tune_anchor, jobs, args.workers):
            results[i] = result
            bar.update(1)
    done = [r for r in results if r is not None]
    holes = sum(args.seeds * (len(r["evaluations"]) + 1) for r in done)
    meta = {
        "command": _command(args),
        "base": args.base,
        "seeds_per_anchor": args.seeds,
        "seed_offset": args.seed_offset,
        "seed_namespace": "tune",
        "evals_per_anchor": args.evals,
        "step": args.step,
        "holes": holes,
        "wall_time_s": round(time.perf_counter() - t0, 1),
        "machine": platform.machine(),
        "objective": "mean paired schedule reward against the base on the same tuning episodes",
    }
    table = build_table(jobs, done, meta)
    out.mkdir(parents=True, exist_ok=True)
    table.save(out / "table.json")
    (out / "anchors.json").write_text(json.dumps(done, indent=1) + "\n")
    write_report(out, table, done)
    print((out / "tune_table.md").read_text())
    print(
        f"Results: {out.resolve()}/ (table.json: make_controller('table:{out / 'table.json'}'), tune_table.md, tune_table.png)"
    )
    return 0


def _command(args: argparse.Namespace) -> str:
    """The ``drillgym tune-table`` command that reproduces this table, every option spelled out."""
    options = {"--base": args.base, "--seeds": args.seeds, "--seed-offset": args.seed_offset, "--evals": args.evals}
    options |= {"--step": f"{args.step:g}", "--out": args.out}
    return shlex.join(["drillgym", "tune-table", *(str(x) for kv in options.items() for x in kv)])
