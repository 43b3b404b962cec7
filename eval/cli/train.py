"""``drillgym train``: one residual training run, or ``--seeds 0,1,2,3,4``: the same configuration on each seed.

Without ``--seeds`` it is one run of :func:`drillgym.training.train.train`; with ``--sweep`` a Ray Tune sweep
(:mod:`drillgym.eval.scale.tune_sweep`). With it, every seed trains in its own process
(``--jobs`` at a time; each run is the single-seed command with ``--seed N --out OUT/seedN``, so any seed's
policy is reproduced by that command alone), then every policy and every baseline are benchmarked on the
same episodes (``--eval-suites``, ``--eval-seeds`` seeds per scenario) and :mod:`drillgym.eval.learning.seed_report` writes the
across-seed report: per-seed checks, interquartile means with stratified-bootstrap CIs and the
probability of improvement over each baseline (``seed_report.md``, ``.json``, ``.png``).

A seed whose ``OUT/seedN/policy.zip`` already exists is not trained again (``--retrain`` forces it): a killed
multi-seed run is continued by running the same command.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

from drillgym.controllers.registry import BEST_CLASSICAL
from drillgym.envs.errors import UserError
from drillgym.training import train
from drillgym.training.config import load_config, resolve_config

POLICY_LABEL = "policy"


def _seeds(text: str) -> list[int]:
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"--seeds expects comma-separated integers, got {text!r}") from e
    if not seeds or len(set(seeds)) != len(seeds) or min(seeds) < 0:
        raise argparse.ArgumentTypeError(f"--seeds {text!r}: give distinct non-negative integers, e.g. 0,1,2,3,4")
    return seeds


def _single_run_arguments(parser: argparse.ArgumentParser) -> None:
    """The options of one training run (and of a sweep)."""
    parser.add_argument("--config", type=Path, default=None, help="YAML overrides of training.config.TrainConfig")
    parser.add_argument("--out", type=Path, required=True, help="run folder (checkpoints, logs, policy)")
    parser.add_argument("--resume", action="store_true", help="continue from the newest checkpoint in --out")
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="start over in an --out that already holds a run (its files are removed)",
    )
    parser.add_argument(
        "--select-only",
        action="store_true",
        help="no training: score the saved models of --out on the validation episodes and export the one "
        "model_selection picks (training.selection)",
    )
    parser.add_argument("--timesteps", type=int, default=None, help="override total_timesteps")
    parser.add_argument("--n-envs", type=int, default=None, help="override n_envs")
    parser.add_argument(
        "--env-workers", type=int, default=None, help="override env_workers (processes drilling a schedule run's holes)"
    )
    parser.add_argument("--seed", type=int, default=None, help="override seed")
    parser.add_argument(
        "--cell-from-diagnosis",
        type=Path,
        default=None,
        metavar="DIAGNOSIS_JSON",
        help="train for the cell a diagnosis found: its named effects at their fitted values (evaluation and "
        "selection), each parameter drawn per training episode within its 95 %% interval (sets cell, cell_ranges)",
    )
    parser.add_argument("--export", type=Path, default=None, help="also copy the best policy bundle here (NAME.zip)")
    parser.add_argument(
        "--torch-threads",
        type=int,
        default=1,
        help="CPU threads of the learner (default 1: the networks are small, and more threads spin-wait "
        "against the env workers and other jobs for the cores)",
    )
    parser.add_argument(
        "--sweep",
        type=Path,
        default=None,
        help="tune hyperparameters on Ray Tune (training/sweeps/*.yaml; implies --ray)",
    )
    parser.add_argument("--ray", action="store_true", help="run the --sweep on Ray (local Ray unless --address)")
    parser.add_argument("--address", default=None, help="Ray cluster for --sweep, e.g. auto or HOST:6379")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The single-run arguments plus the multi-seed ones."""
    _single_run_arguments(parser)
    group = parser.add_argument_group("several training seeds (--seeds)")
    group.add_argument("--seeds", type=_seeds, default=None, help="train each of these seeds, e.g. 0,1,2,3,4")
    group.add_argument("--jobs", type=int, default=2, help="training runs at a time (default 2)")
    group.add_argument("--retrain", action="store_true", help="train seeds that already have a policy again")
    group.add_argument(
        "--baselines",
        default=f"li2023,{BEST_CLASSICAL},table:shipped",
        help=f"baseline controller specs to judge the policies against (default li2023,{BEST_CLASSICAL},table:shipped: "
        "the gain-scheduling table of drillgym tune-table)",
    )
    group.add_argument(
        "--best-baseline",
        default="auto",
        help=f"the strongest baseline, or auto (default): {BEST_CLASSICAL} unless another classical baseline beats it "
        "by the seed report's own checks (drillgym.eval.learning.best_classical)",
    )
    group.add_argument("--reference", default="li2023", help="the paper's compensator (default li2023)")
    group.add_argument(
        "--eval-suites",
        default="paper,generalisation,heldout",
        help="suites to judge on (default paper,generalisation,heldout)",
    )
    group.add_argument("--eval-seeds", type=int, default=20, help="episode seeds per scenario (default 20)")
    group.add_argument("--workers", type=int, default=2, help="benchmark worker processes (default 2)")


def run(args: argparse.Namespace) -> int:
    """Single run (no ``--seeds``) or train several seeds, benchmark them and write the seed report."""
    if args.sweep is not None or args.ray or args.address:  # a Ray Tune sweep (imports nothing of Ray before)
        return _sweep(args)
    if args.seeds is None:
        return _single_run(args)
    baselines = _check(args)  # bad arguments raise ValueError: the CLI prints it on one line
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    failed = train_seeds(args, out)
    if failed:
        print(f"drillgym train: seeds {failed} failed; see {out}/seed<N>.log", file=sys.stderr)
        return 1
    return judge(args, out, baselines)


def _overrides(args: argparse.Namespace) -> dict[str, Any]:
    """``--timesteps``, ``--n-envs``, ``--seed`` and ``--cell-from-diagnosis`` as configuration overrides (those given)."""
    given = (
        ("total_timesteps", args.timesteps),
        ("n_envs", args.n_envs),
        ("env_workers", args.env_workers),
        ("seed", args.seed),
    )
    out = {k: v for k, v in given if v is not None}
    if args.cell_from_diagnosis is not None:
        from drillgym.eval.diagnosis.training_cell import cell_overrides

        out.update(cell_overrides(args.cell_from_diagnosis))
    return out


def _single_run(args: argparse.Namespace) -> int:
    """One training run (or ``--select-only``); a bad ``--out``/``--config`` raises ``ValueError``."""
    if args.select_only:
        policy = train.select_only(args.out, args.config, args.export)
        print(f"policy: {policy.resolve()}")
        return 0
    import torch

    if args.torch_threads:
        torch.set_num_threads(max(int(args.torch_threads), 1))
    train.check_run_folder(args.out, args.resume, args.overwrite)
    cfg = load_config(args.out / "config.yaml" if args.resume else args.config, _overrides(args))
    if args.overwrite:
        train.clear_run(args.out)
    train.train(cfg, args.out, resume=args.resume, export=args.export)
    return 0


def _sweep(args: argparse.Namespace) -> int:
    """``--sweep SPEC.yaml [--ray] [--address ADDR]``: tune residual training on Ray Tune, export the best policy.

    The sweep file is read and checked by :func:`drillgym.training.sweep.load_sweep`; the trials run in
    :mod:`drillgym.eval.scale.tune_sweep`.
    """
    from drillgym.training.sweep import load_sweep

    if args.sweep is None:
        raise UserError("--ray/--address need --sweep SPEC.yaml (a single run trains on one machine)")
    if args.resume:
        raise UserError("--resume does not apply to --sweep (a failed trial restarts from its checkpoint)")
    from drillgym.eval.scale.cluster import require_ray

    require_ray()
    spec = load_sweep(args.sweep, _overrides(args), args.config)
    from drillgym.eval.scale.tune_sweep import run_sweep

    outcome = run_sweep(spec, args.out, args.address, export=args.export)
    return 0 if outcome.best is not None else 1


def _check(args: argparse.Namespace) -> list[str]:
    from drillgym.controllers import make_controller
    from drillgym.eval.bench.jobs import split_controller_specs

    if args.resume or args.export or args.sweep is not None:
        raise UserError("--seeds cannot be combined with --resume, --export or --sweep")
    if args.jobs < 1 or args.workers < 1 or args.eval_seeds < 2:
        raise UserError("--jobs and --workers must be >= 1, --eval-seeds >= 2")
    if args.config is not None:
        args.config = resolve_config(args.config)
    from drillgym.training.env_factory import batched_schedule  # Stable-Baselines3's imports, only here

    cfg = load_config(args.config, _overrides(args))  # the configuration every seed will train with, checked now
    processes = args.jobs * (cfg.env_workers if batched_schedule(cfg) else max(cfg.n_envs, 1))
    cpus = os.cpu_count() or 1
    if processes > cpus:
        print(
            f"drillgym train: --jobs {args.jobs} runs of {processes // args.jobs} env process(es) each on {cpus} CPUs: "
            "the seeds will share cores (slower, the same results)",
            file=sys.stderr,
        )
    baselines = split_controller_specs(args.baselines)
    named = {args.reference} | ({BEST_CLASSICAL} if args.best_baseline == "auto" else {args.best_baseline})
    for spec in {*baselines, *named}:
        make_controller(spec)
    missing = named - set(baselines)
    if missing:
        raise UserError(f"--baselines {args.baselines!r} must include {sorted(missing)}")
    return baselines


def seed_command(args: argparse.Namespace, seed: int, out: Path) -> list[str]:
    """The single-seed ``drillgym train`` command of one seed (what reproduces its policy)."""
    cmd = [sys.executable, "-m", "drillgym.eval.cli", "train", "--out", str(out), "--seed", str(seed)]
    if args.config is not None:
        cmd += ["--config", str(args.config)]
    for flag, value in (
        ("--timesteps", args.timesteps),
        ("--n-envs", args.n_envs),
        ("--env-workers", args.env_workers),
        ("--cell-from-diagnosis", args.cell_from_diagnosis),
    ):
        if value is not None:
            cmd += [flag, str(value)]
    if args.retrain:
        cmd.append("--overwrite")
    return [*cmd, "--torch-threads", str(args.torch_threads)]


def train_seeds(args: argparse.Namespace, out: Path) -> list[int]:
    """Train the seeds that lack a policy, ``--jobs`` at a time; the seeds whose run failed."""
    todo = [s for s in args.seeds if args.retrain or not (out / f"seed{s}" / "policy.zip").exists()]
    unfinished = [s for s in todo if (out / f"seed{s}").exists() and not args.retrain]
    if unfinished:
        raise UserError(
            f"seeds {unfinished} have a run folder but no policy.zip (a killed run?): continue each with "
            f"drillgym train --out {out}/seed<N> --resume, or start them over with --retrain"
        )
    for s in sorted(set(args.seeds) - set(todo)):
        print(f"seed {s}: {out / f'seed{s}' / 'policy.zip'} exists, not trained again (--retrain to force)")

    def one(seed: int) -> tuple[int, int, float]:
        folder = out / f"seed{seed}"
        t0 = time.perf_counter()
        with open(out / f"seed{seed}.log", "w") as log:
            rc = subprocess.run(seed_command(args, seed, folder), stdout=log, stderr=subprocess.STDOUT).returncode
        wall = time.perf_counter() - t0
        print(f"seed {seed}: exit {rc} after {wall / 60:.1f} min ({out / f'seed{seed}.log'})", flush=True)
        return seed, rc, wall

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        results = list(pool.map(one, todo))
    if todo:
        print(f"trained {len(todo)} seeds in {(time.perf_counter() - t0) / 60:.1f} min, {args.jobs} at a time")
    return [seed for seed, rc, _ in results if rc != 0]


def _protocol(
    args: argparse.Namespace, out: Path, frame: Any, baselines: list[str]
) -> tuple[str, dict[str, Any], list[str]]:
    """The best classical baseline (``--best-baseline auto``) and the seed the configuration's rule ships."""
    from drillgym.eval.learning import best_classical, ship_rule

    lines: list[str] = []
    extra: dict[str, Any] = {}
    best = args.best_baseline
    if best == "auto":
        candidates = [b for b in baselines if b != args.reference]
        best, rows = best_classical.choose_best_classical(frame, candidates, BEST_CLASSICAL, args.reference)
        extra["best_classical"] = {"rule": best_classical.RULE, "chosen": best, "candidates": rows}
        lines += best_classical.describe(best, BEST_CLASSICAL, rows)
        suites = [s for s in ("paper", "generalisation", "heldout") if s in set(frame["suite"])]
        each = best_classical.against_each(
            frame, [BEST_CLASSICAL, *(c for c in candidates if c != BEST_CLASSICAL)], suites
        )
        extra["against_each_classical"] = each
        lines += best_classical.describe_against_each(each, suites)
    rule = load_config(args.config).ship_rule
    rows = ship_rule.selection_rows(out, list(args.seeds))
    shipped = ship_rule.ship_seed(rows, rule)
    extra["ship"] = {"rule": rule, "seed": shipped, "seeds": rows}
    lines += ship_rule.describe(rows, rule, shipped)
    return best, extra, lines


def judge(args: argparse.Namespace, out: Path, baselines: list[str]) -> int:
    """Benchmark every seed's policy and the baselines on the same episodes; write the seed report."""
    import pandas as pd

    from drillgym.eval.bench.episode import grid_jobs
    from drillgym.eval.bench.jobs import run_jobs
    from drillgym.eval.bench.report import episodes_frame
    from drillgym.eval.learning.schedule_map import plot_schedule_map, schedule_table
    from drillgym.eval.learning.seed_report import write_seed_report

    suites = [s.strip() for s in args.eval_suites.split(",") if s.strip()]
    policies = {f"seed{s}": f"residual:{out / f'seed{s}' / 'policy.zip'}" for s in args.seeds}
    specs = [*baselines, *policies.values()]
    cell = load_config(args.config, _overrides(args)).training_cell().nominal_spec()  # judged in the cell trained for
    jobs = grid_jobs(suites, specs, args.eval_seeds, cell=cell)
    frame = episodes_frame(run_jobs(jobs, args.workers, desc="judge seeds"))
    run_of = {spec: run for run, spec in policies.items()}
    frame.insert(0, "run", [run_of.get(c, "") for c in frame["controller"]])
    frame["controller"] = [POLICY_LABEL if c in run_of else c for c in frame["controller"]]
    frame.to_csv(out / "seed_episodes.csv", index=False)
    errors = frame[frame["error"].fillna("") != ""]
    if len(errors):
        print(f"drillgym train: {len(errors)} evaluation episodes failed; see seed_episodes.csv", file=sys.stderr)
        return 1
    best, extra, lines = _protocol(args, out, frame, baselines)
    if cell:
        lines = [f"Judged in the cell the seeds were trained for: `{cell}` (every suite, every controller).", *lines]
    write_seed_report(pd.DataFrame(frame), out, best, reference=args.reference, extra=extra, extra_markdown=lines)
    print((out / "seed_report.md").read_text())
    files = "seed_report.md, seed_report.json, seed_report.png, seed_episodes.csv"
    table = schedule_table(policies, suites)
    if len(table):  # schedule residuals: what each seed sets for each scenario's plan
        table.to_csv(out / "schedule_map.csv", index=False)
        plot_schedule_map(table, out / "schedule_map.png")
        files += ", schedule_map.csv, schedule_map.png"
    print(f"Results: {out.resolve()}/ ({files})")
    return 0
