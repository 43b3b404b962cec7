"""``drillgym bench``: controllers × scenarios × seeds, with CIs, paired differences, plots and logs.

Every controller runs the same seeds 0..N-1 on every scenario of the suite (a paired comparison; the
first controller is the baseline). Episodes run in ``--workers`` processes ("spawn": PyBullet and fork
do not mix), or as Ray tasks with ``--ray`` / ``--address`` (:mod:`drillgym.eval.scale.bench_ray`,
``docs/scale-out.md``); the results do not depend on either. Outputs in ``--out``: see
:mod:`drillgym.eval.bench.report`; one episode log per episode in ``logs/`` (``docs/log_schema.md``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from drillgym.controllers.registry import BEST_CLASSICAL
from drillgym.envs.effects.cells import cell_effects_spec
from drillgym.eval.bench.jobs import controller_label, run_jobs, split_controller_specs
from drillgym.eval.bench.suites import SUITES


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--suite", default="paper", help=f"scenario suite: {', '.join(SUITES)} (default paper)")
    parser.add_argument(
        "--controllers",
        default=f"none,li2023,{BEST_CLASSICAL}",
        help="comma-separated controller specs, the first is the baseline, e.g. none,li2023,li2023:kp=1.0,ki=0.5 "
        f"(a field=value item continues the spec before it; {BEST_CLASSICAL} is the strongest classical baseline; "
        f"default none,li2023,{BEST_CLASSICAL})",
    )
    parser.add_argument(
        "--cell",
        default="ideal",
        help="cell: ideal (no unmodelled effect) or li2023-lab (the effect fitted to Li's runs, docs/explain-paper.md); "
        "default ideal",
    )
    parser.add_argument("--seeds", type=int, default=5, help="seeds 0..N-1 per scenario and controller (default 5)")
    parser.add_argument("--out", type=Path, default=Path("results/bench"), help="output folder (default results/bench)")
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        help="parallel worker processes (default 1: in-process); with --ray: CPUs of the local Ray",
    )
    parser.add_argument("--no-logs", action="store_true", help="do not write per-episode Parquet logs")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a previous run in --out (its CSVs, report and logs/); without it such an --out is an error",
    )
    parser.add_argument(
        "--ray",
        action="store_true",
        help="run the episodes as Ray tasks (local Ray unless --address; docs/scale-out.md)",
    )
    parser.add_argument(
        "--address", default=None, help="Ray cluster to run on, e.g. auto or HOST:6379 (implies --ray; default: local)"
    )


RUN_FILES = ("episodes.csv", "summary.csv", "paired.csv", "summary.md", "errors.log")
"""What a benchmark run writes at the top of its folder (plus plots and ``logs/``)."""


def previous_run(out: Path) -> list[str]:
    """Names of a previous run's files in ``out`` (empty when there is none)."""
    found = [name for name in RUN_FILES if (out / name).exists()]
    logs = out / "logs"
    if logs.is_dir() and any(logs.glob("*.parquet")):
        found.append("logs/")
    return found


def clear_previous_run(out: Path) -> None:
    """Remove a previous run's files, plots and Parquet logs from ``out`` (nothing else)."""
    for name in RUN_FILES:
        (out / name).unlink(missing_ok=True)
    plots = [*out.glob("*_deviation_force.png"), *out.glob("sweep_*_vs_*.png")]
    for path in [*plots, *(out / "logs").glob("*.parquet")]:
        path.unlink()


def check_arguments(args: argparse.Namespace) -> list[str]:
    """Controller specs after validating every argument (raises ``ValueError`` with a clear message)."""
    from drillgym.controllers import make_controller

    if args.suite not in SUITES:
        raise ValueError(f"unknown suite {args.suite!r}; choose from {', '.join(SUITES)}")
    if args.seeds < 1:
        raise ValueError(f"--seeds={args.seeds} must be >= 1")
    cell_effects_spec(getattr(args, "cell", "ideal"))
    if args.workers < 1:
        raise ValueError(f"--workers={args.workers} must be >= 1")
    previous = previous_run(args.out)
    if previous and not getattr(args, "overwrite", False):
        raise ValueError(
            f"{args.out} holds a previous run ({', '.join(previous[:3])}{', ...' if len(previous) > 3 else ''}); "
            "pass --overwrite to replace it, or another --out (logs of two runs side by side would mix in a diagnosis)"
        )
    if getattr(args, "ray", False) or getattr(args, "address", None):
        from drillgym.eval.scale.cluster import require_ray

        require_ray()
    specs = split_controller_specs(args.controllers)
    if len(set(specs)) != len(specs):
        raise ValueError(f"--controllers lists a spec twice: {specs}")
    for spec in specs:
        try:
            make_controller(spec)
        except (ValueError, TypeError, OSError) as e:
            raise ValueError(f"bad controller spec {spec!r}: {e}") from e
    labels = [controller_label(s) for s in specs]
    if len(set(labels)) != len(labels):
        raise ValueError(f"controller specs {specs} give clashing file labels {labels}")
    return specs


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym bench`` (bad arguments raise ``ValueError`` for the CLI's one-line error)."""
    specs = check_arguments(args)
    from drillgym.eval.bench.episode import EpisodeJob
    from drillgym.eval.bench.report import write_report
    from drillgym.eval.bench.suites import suite_scenarios

    out: Path = args.out
    scenarios = suite_scenarios(args.suite)
    effects = cell_effects_spec(getattr(args, "cell", "ideal"))
    jobs = []
    for sc in scenarios:
        for spec in specs:
            for seed in range(args.seeds):
                name = f"logs/{args.suite}__{sc.name}__{controller_label(spec)}__seed{seed}.parquet"
                log = None if args.no_logs else out / name
                jobs.append(
                    EpisodeJob(args.suite, sc.name, sc.kwargs, spec, seed, log, "" if log is None else name, effects)
                )
    if getattr(args, "overwrite", False):
        clear_previous_run(out)
    (out if args.no_logs else out / "logs").mkdir(parents=True, exist_ok=True)
    if getattr(args, "ray", False) or getattr(args, "address", None):
        from drillgym.eval.scale.bench_ray import run_jobs_ray

        cpus = args.workers if args.workers > 1 else None  # a local Ray's CPUs (default: the machine's)
        rows = run_jobs_ray(jobs, out, args.address, desc=f"bench {args.suite}", num_cpus=cpus).rows
    else:
        rows = run_jobs(jobs, args.workers, desc=f"bench {args.suite}")
    episodes = write_report(out, rows, args.suite, [s.name for s in scenarios], specs, args.seeds)
    if effects:
        summary = out / "summary.md"
        note = f"Cell: {args.cell} (unmodelled effects on: `{effects}`; docs/explain-paper.md).\n\n"
        summary.write_text(note + summary.read_text())
    print((out / "summary.md").read_text())
    print(
        f"Results: {out.resolve()}/ (episodes.csv, summary.csv, paired.csv, summary.md, plots{', logs/' * (not args.no_logs)})"
    )
    failed = episodes[episodes["error"].fillna("") != ""]
    if len(failed):
        print(f"drillgym bench: {len(failed)} of {len(episodes)} episodes failed:", file=sys.stderr)
        for r in failed.itertuples(index=False):
            print(f"  {r.scenario} {r.controller} seed {r.seed}: {r.error}", file=sys.stderr)
        print(f"  tracebacks: {out / 'errors.log'}", file=sys.stderr)
        return 1
    return 0
