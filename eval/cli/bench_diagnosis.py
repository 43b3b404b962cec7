"""``drillgym bench-diagnosis [--quick] --out DIR``: the withheld-effect benchmark of the diagnosis."""

from __future__ import annotations

import argparse
import dataclasses
import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drillgym.envs.errors import UserError

if TYPE_CHECKING:
    from collections.abc import Callable

    from drillgym.eval.diagnosis.bench.cases import Case


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
        "--seed-offsets",
        default="",
        metavar="N,N,...",
        help="run the benchmark once per offset (into OUT/offset-N) and pool every case of every run in OUT/bench.md, "
        "e.g. 0,1000,2000: one offset's handful of pairs and clean cases makes each figure coarse",
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
    from drillgym.eval.diagnosis.bench.run import run_bench

    if args.quick and args.opt_in:
        raise UserError("--opt-in adds full-size cases; it cannot be combined with --quick")
    offsets = _offsets(args.seed_offsets)
    if offsets and args.seed_offset:
        raise UserError("give --seed-offset or --seed-offsets, not both")
    cases = _cases(args)
    episodes = args.episodes or (6 if args.quick else 12)
    candidates = _candidates(args)
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

    def run_cases(cs: list[Case], out: Path) -> dict[str, Any]:
        # a Ray cluster that cannot be reached raises ConnectionError: the CLI's one-line error
        return run_bench(
            cs,
            episodes,
            candidates,
            out,
            args.workers,
            progress=not args.no_progress,
            rows_of=rows_of,
            best_equivalent=best,
        )

    if offsets:
        return _run_offsets(cases, offsets, args.out, run_cases)
    result = run_cases(cases, args.out)
    for k, v in result["summary"]["figures"].items():
        print(f"{k}: {v}")
    print(f"wrote {args.out / 'bench.json'} and {args.out / 'bench.md'}")
    return 0


def _cases(args: argparse.Namespace) -> list[Case]:
    """The cases asked for (``--quick``, ``--opt-in``, ``--only``, ``--seed-offset``); an unknown name is refused."""
    from drillgym.eval.diagnosis.bench.cases import full_cases, quick_cases

    cases: list[Case] = quick_cases() if args.quick else full_cases(opt_in=args.opt_in)
    if args.only:
        wanted = {c.strip() for c in args.only.split(",") if c.strip()}
        unknown = sorted(wanted - {c.name for c in cases})
        if unknown:
            raise UserError(f"unknown case(s) {unknown}; cases: {', '.join(c.name for c in cases)}")
        cases = [c for c in cases if c.name in wanted]
    if args.seed_offset:
        cases = [dataclasses.replace(c, seed=c.seed + args.seed_offset) for c in cases]
    return cases


def _candidates(args: argparse.Namespace) -> tuple[str, ...]:
    """The candidate effects: ``--candidates``, else the defaults (quick: three; ``--opt-in``: and the opt-in ones)."""
    from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES, parse_candidates
    from drillgym.eval.diagnosis.bench.cases import QUICK_CANDIDATES, opt_in_candidates

    if args.candidates:
        return tuple(parse_candidates(args.candidates))
    candidates = QUICK_CANDIDATES if args.quick else DIAGNOSIS_CANDIDATES
    return (*candidates, *opt_in_candidates()) if args.opt_in else tuple(candidates)


def _run_offsets(
    cases: list[Case], offsets: list[int], out: Path, run_cases: Callable[[list[Case], Path], dict[str, Any]]
) -> int:
    """Run every offset, pool and print the pooled counts."""
    from drillgym.eval.diagnosis.bench.offsets import KINDS, run_offsets

    pooled = run_offsets(cases, offsets, out, run_cases)
    for kind in KINDS:
        c = pooled["pooled"][kind]
        print(f"{kind}: {c['right']}/{c['cases']} right over seed offsets {','.join(map(str, offsets))}")
    print(f"false attributions: {len(pooled['pooled']['false_attributions'])}")
    print(f"wrote {out / 'bench.json'} and {out / 'bench.md'} (each offset's run in {out}/offset-N)")
    return 0


def _offsets(text: str) -> list[int]:
    """The seed offsets of ``--seed-offsets`` (none for ``''``)."""
    try:
        offsets = [int(t) for t in text.split(",") if t.strip()]
    except ValueError:
        raise UserError(f"--seed-offsets takes comma-separated integers, e.g. 0,1000,2000; got {text!r}") from None
    from drillgym.eval.diagnosis.bench.offsets import check_offsets

    check_offsets(offsets)
    return offsets
