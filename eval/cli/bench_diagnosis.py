"""``drillgym bench-diagnosis [--quick] --out DIR``: the withheld-effect benchmark of the diagnosis."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path

from drillgym.envs.errors import UserError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", required=True, type=Path, help="output folder: bench.json, bench.md, cases/")
    parser.add_argument("--quick", action="store_true", help="test-sized: 3 cases, 6 episodes, 3 candidates")
    parser.add_argument("--episodes", type=int, default=None, help="episodes per case (default 12; quick 6)")
    parser.add_argument(
        "--workers", type=int, default=os.cpu_count() or 1, help="cases run in parallel (default: all cores)"
    )
    parser.add_argument("--only", default="", help="comma-separated case names to run (default: all)")
    parser.add_argument(
        "--seed-offset",
        type=int,
        default=0,
        help="added to every case's seed: the same cases on other episodes and specimens (default 0)",
    )
    parser.add_argument(
        "--candidates",
        default="",
        help="comma-separated candidate effects (default: diagnose's defaults; quick: three); e.g. the defaults "
        "plus opt-in ones, to benchmark them before they become defaults",
    )
    parser.add_argument(
        "--opt-in",
        action="store_true",
        help="also the cases of the opt-in candidates' realities (ft_load_bias, bone_registration, ft_lateral_gain), "
        "with those candidates added to the defaults (unless --candidates names the list)",
    )
    parser.add_argument(
        "--pseudo-truth",
        type=Path,
        default=None,
        metavar="FILE",
        help="also score the parameter intervals against each candidate's best equivalent of its reality (its fit "
        "on 36 fresh episodes): read from FILE, the missing ones computed first and written there (reuse FILE "
        "across --seed-offset runs)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--ray", action="store_true", help="run the cases as Ray tasks (a local instance by default)")
    parser.add_argument(
        "--address", default=None, help="Ray cluster address (implies --ray): HOST:6379, auto, ray://..."
    )


def run(args: argparse.Namespace) -> int:
    """Run the benchmark and print its figures."""
    from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES, parse_candidates
    from drillgym.eval.diagnosis.bench.cases import QUICK_CANDIDATES, Case, full_cases, opt_in_candidates, quick_cases
    from drillgym.eval.diagnosis.bench.run import run_bench

    if args.quick and args.opt_in:
        raise UserError("--opt-in adds full-size cases; it cannot be combined with --quick")
    cases: list[Case] = quick_cases() if args.quick else full_cases(opt_in=args.opt_in)
    if args.only:
        wanted = {c.strip() for c in args.only.split(",") if c.strip()}
        unknown = sorted(wanted - {c.name for c in cases})
        if unknown:
            print(
                f"drillgym bench-diagnosis: error: unknown case(s) {unknown}; cases: {', '.join(c.name for c in cases)}",
                file=sys.stderr,
            )
            return 2
        cases = [c for c in cases if c.name in wanted]
    if args.seed_offset:
        cases = [dataclasses.replace(c, seed=c.seed + args.seed_offset) for c in cases]
    episodes = args.episodes or (6 if args.quick else 12)
    candidates = QUICK_CANDIDATES if args.quick else DIAGNOSIS_CANDIDATES
    if args.opt_in and not args.candidates:
        candidates = (*candidates, *opt_in_candidates())
    if args.candidates:
        candidates = parse_candidates(args.candidates)
    rows_of = None
    if args.ray or args.address:
        from drillgym.eval.scale.cluster import require_ray

        require_ray()
        from drillgym.eval.diagnosis.bench.on_ray import ray_rows

        rows_of = lambda jobs: ray_rows(jobs, args.address, args.workers)  # noqa: E731
    best = None
    if args.pseudo_truth is not None:
        from drillgym.eval.diagnosis.bench.pseudo_truth import load_or_compute

        best = load_or_compute(args.pseudo_truth, cases, args.workers)
    result = run_bench(  # a Ray cluster that cannot be reached raises ConnectionError: the CLI's one-line error
        cases,
        episodes,
        candidates,
        args.out,
        args.workers,
        progress=not args.no_progress,
        rows_of=rows_of,
        best_equivalent=best,
    )
    for k, v in result["summary"]["figures"].items():
        print(f"{k}: {v}")
    print(f"wrote {args.out / 'bench.json'} and {args.out / 'bench.md'}")
    return 0
