"""``drillgym bench``: controllers × scenarios × seeds, with CIs, paired differences, plots and logs.

Every controller runs the same seeds 0..N-1 on every scenario of the suite (a paired comparison against
the ``--reference`` controller, by default the first), and ``summary.md`` gives one verdict per metric
and controller: lower than, higher than, or no significant difference from the reference. Episodes run in
``--workers`` processes ("spawn": PyBullet and fork do not mix), or as Ray tasks with ``--ray`` /
``--address`` (:mod:`drillgym.eval.scale.bench_ray`, ``docs/scale-out.md``); the results do not depend on
either. Outputs in ``--out``: see :mod:`drillgym.eval.bench.report`; one episode log per episode in
``logs/`` (``docs/log_schema.md``). Each finished episode is appended to ``episodes.csv`` at once, so an
interrupted run keeps them, and ``--resume`` runs only the rest.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import sys
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

from drillgym.controllers.registry import BEST_CLASSICAL
from drillgym.envs.effects.cells import cell_effects_spec
from drillgym.envs.errors import UserError, read_json
from drillgym.envs.scenario import Scenario
from drillgym.eval.bench.jobs import controller_label, reference_spec, run_jobs, split_controller_specs
from drillgym.eval.bench.suites import SUITES

if TYPE_CHECKING:
    import pandas as pd

    from drillgym.eval.bench.episode import EpisodeJob


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--suite", default="paper", help=f"scenario suite: {', '.join(SUITES)} (default paper)")
    parser.add_argument(
        "--controllers",
        default=f"none,li2023,{BEST_CLASSICAL}",
        help="comma-separated controller specs, e.g. none,li2023,li2023:kp=1.0,ki=0.5 "
        f"(a field=value item continues the spec before it; {BEST_CLASSICAL} is the strongest classical baseline; "
        f"default none,li2023,{BEST_CLASSICAL})",
    )
    parser.add_argument(
        "--reference",
        default=None,
        help="the controller the paired differences and verdicts are taken against: one of --controllers, as "
        "written or as its file label (li2023_kp-1.0 for li2023:kp=1.0); default: the first",
    )
    parser.add_argument(
        "--reality",
        default="",
        metavar="SPEC",
        help="effects of the reality library (drillgym make-reality --help) on every episode, beside --cell: judge "
        "controllers in a simulated reality, e.g. the one a diagnosis was tested on; default none",
    )
    parser.add_argument(
        "--cell",
        default="ideal",
        help="cell: ideal (no unmodelled effect), li2023-lab (the effect fitted to Li's runs, docs/explain-paper.md) "
        "or an effect spec (joint_friction:coulomb_rad=4e-4, a diagnosed cell); default ideal",
    )
    parser.add_argument(
        "--seeds",
        type=int,
        default=5,
        help="seeds 0..N-1 per scenario and controller (default 5; fewer than 20 warns: wide CIs)",
    )
    parser.add_argument("--out", type=Path, default=Path("results/bench"), help="output folder (default results/bench)")
    parser.add_argument(
        "--workers",
        type=int,
        default=1,
        help="parallel worker processes (default 1: in-process); with --ray: CPUs of the local Ray",
    )
    parser.add_argument("--no-logs", action="store_true", help="do not write per-episode Parquet logs")
    again = parser.add_mutually_exclusive_group()
    again.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a previous run in --out (its CSVs, report and logs/); without it such an --out is an error",
    )
    again.add_argument(
        "--resume",
        action="store_true",
        help="finish an interrupted run in --out: keep the episodes of its episodes.csv that finished without "
        "error (and whose log is there), run the rest, then write the whole report as an uninterrupted run would. "
        "The run must have had the same --suite, --controllers, --cell, --seeds and --no-logs (else an error); "
        "--workers, --ray and --reference may differ (a finished run is then only re-reported)",
    )
    parser.add_argument(
        "--ray",
        action="store_true",
        help="run the episodes as Ray tasks (local Ray unless --address; docs/scale-out.md)",
    )
    parser.add_argument(
        "--address", default=None, help="Ray cluster to run on, e.g. auto or HOST:6379 (implies --ray; default: local)"
    )


RUN_JSON = "run.json"
"""The settings that define a run's episodes (:func:`run_settings`), written when it starts; ``--resume`` checks them."""
RUN_FILES = ("episodes.csv", "summary.csv", "paired.csv", "summary.md", "errors.log", RUN_JSON)
"""What a benchmark run writes at the top of its folder (plus plots and ``logs/``)."""
TEXT_COLUMNS = (
    "suite",
    "scenario",
    "controller",
    "failure",
    "error",
    "log",
    *(f.name for f in fields(Scenario) if f.type in ("str", str)),
)
"""Columns of ``episodes.csv`` read back as text (an empty cell is ``""``, a name such as ``1`` stays a name)."""


LOG_FOLDERS = (("logs", "*.parquet"),)
"""Folders of a benchmark run's logs, each with the pattern of what it holds."""


def previous_run(
    out: Path, files: Sequence[str] = RUN_FILES, folders: Sequence[tuple[str, str]] = LOG_FOLDERS
) -> list[str]:
    """Names of a previous run's files in ``out`` (empty when there is none).

    ``files``: what a run writes at the top of its folder; ``folders``: ``(folder, pattern)`` of what it writes in
    sub-folders, reported as ``folder/``. The defaults are a benchmark run's; ``drillgym run`` and ``diagnose`` pass
    their own (a run's record is never overwritten).
    """
    found = [name for name in files if (out / name).exists()]
    for folder, pattern in folders:
        if (out / folder).is_dir() and any((out / folder).glob(pattern)):
            found.append(f"{folder}/")
    return found


def refuse_previous_record(out: Path, files: Sequence[str], overwrite: bool, what: str) -> None:
    """Refuse an ``--out`` that is a file, or that holds a previous ``what``'s ``files`` unless ``overwrite``.

    A command's record is never overwritten by accident: the message names the files found and the ways out.
    """
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out} exists and is not a folder")
    found = previous_run(out, files, ())
    if found and not overwrite:
        raise UserError(
            f"--out {out} holds a previous {what} ({', '.join(found)}); pass --overwrite to replace it, or another --out"
        )


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
        raise UserError(f"unknown suite {args.suite!r}; choose from {', '.join(SUITES)}")
    if args.seeds < 1:
        raise UserError(f"--seeds={args.seeds} must be >= 1")
    _check_cell_and_reality(args)
    if args.workers < 1:
        raise UserError(f"--workers={args.workers} must be >= 1")
    resume = getattr(args, "resume", False)
    if resume and getattr(args, "overwrite", False):
        raise UserError("--resume and --overwrite exclude each other")
    previous = previous_run(args.out)
    if previous and not getattr(args, "overwrite", False) and not resume:
        raise UserError(
            f"{args.out} holds a previous run ({', '.join(previous[:3])}{', ...' if len(previous) > 3 else ''}); "
            "pass --overwrite to replace it, --resume to finish it, or another --out "
            "(logs of two runs side by side would mix in a diagnosis)"
        )
    if getattr(args, "ray", False) or getattr(args, "address", None):
        from drillgym.eval.scale.cluster import require_ray

        require_ray()
    specs = split_controller_specs(args.controllers)
    if len(set(specs)) != len(specs):
        raise UserError(f"--controllers lists a spec twice: {specs}")
    for spec in specs:
        try:
            make_controller(spec)
        except (ValueError, TypeError, OSError) as e:
            raise UserError(f"bad controller spec {spec!r}: {e}") from e
    labels = [controller_label(s) for s in specs]
    if len(set(labels)) != len(labels):
        raise UserError(f"controller specs {specs} give clashing file labels {labels}")
    reference_spec(specs, getattr(args, "reference", None))
    if resume:
        check_resume(args, specs)
    return specs


def _check_cell_and_reality(args: argparse.Namespace) -> None:
    """``--cell`` names a cell or an effect spec; ``--reality`` is a spec of the reality library."""
    cell_effects_spec(getattr(args, "cell", "ideal"))
    if getattr(args, "reality", ""):
        from drillgym.eval.diagnosis.reality.generate import build_reality

        build_reality(args.reality)


def run_settings(args: argparse.Namespace, specs: list[str]) -> dict[str, Any]:
    """What defines a run's episodes (``run.json``): ``--resume`` needs the same."""
    cell = getattr(args, "cell", "ideal")
    settings = {"suite": args.suite, "controllers": specs, "cell": cell, "seeds": args.seeds, "logs": not args.no_logs}
    if getattr(args, "reality", ""):  # absent from the run.json of a run without one, as before the option
        settings["reality"] = args.reality
    return settings


def check_resume(args: argparse.Namespace, specs: list[str]) -> None:
    """Raise ``ValueError`` unless ``--out`` holds a run that this command can resume."""
    out: Path = args.out
    if not (out / "episodes.csv").is_file():
        raise UserError(f"--resume: {out / 'episodes.csv'} does not exist, so there is nothing to resume")
    if not (out / RUN_JSON).is_file():
        return  # a run from before run.json: finished_rows still checks every episode against the grid
    then = {"reality": "", **read_json(out / RUN_JSON)}  # a run without --reality has none in its run.json
    now = {"reality": "", **run_settings(args, specs)}
    changed = [f"{key} {then.get(key)!r} then, {value!r} now" for key, value in now.items() if then.get(key) != value]
    if changed:
        raise UserError(
            f"--resume: the run in {out} had other settings ({'; '.join(changed)}); "
            "rerun its command with --resume, or pass --overwrite to start afresh"
        )


def finished_rows(out: Path, jobs: list[EpisodeJob]) -> list[dict[str, Any]]:
    """The rows of ``out/episodes.csv`` that ``--resume`` keeps: one per job that finished without error.

    A row is kept when its ``error`` is empty, its ``wall_time_s`` is there (a row cut short by a crash is run
    again), and it names the job's log, which exists (``logs/``); an episode that is not a job raises ``ValueError``
    (the check that remains for a run from before ``run.json``, whose ``--cell`` cannot be checked).
    """
    frame = read_episodes_csv(out / "episodes.csv")
    by_key = {job.key: job for job in jobs}
    kept: dict[tuple[str, str, str, int], dict[str, Any]] = {}
    for record in frame.to_dict("records"):
        row = {str(k): v for k, v in record.items()}
        for c in TEXT_COLUMNS:
            if c in row and not isinstance(row[c], str):
                row[c] = ""  # an empty cell
        key = (row["suite"], row["scenario"], row["controller"], int(row["seed"]))
        job = by_key.get(key)
        if job is None:
            raise UserError(
                f"--resume: {out / 'episodes.csv'} holds an episode this command does not run "
                f"({key[0]} {key[1]} {key[2]} seed {key[3]}); rerun that run's command, or pass --overwrite"
            )
        if _finished(row, job.log_name, out):
            kept[key] = row
    return list(kept.values())


def read_episodes_csv(path: Path) -> pd.DataFrame:
    """``episodes.csv`` as written: floats to the bit (pandas 2 needs ``round_trip`` for that), names as text."""
    import pandas as pd

    dtypes = {c: str for c in TEXT_COLUMNS}
    exact: dict[str, Any] = {} if int(pd.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
    try:
        return pd.read_csv(
            path, dtype=dtypes, keep_default_na=False, na_values=[""], **exact
        )  # pandas 3: exact already
    except ValueError as e:  # pandas' ParserError and EmptyDataError
        raise UserError(f"{path}: not a readable episodes.csv ({e})") from e


def _finished(row: dict[str, Any], log_name: str, out: Path) -> bool:
    """Whether an ``episodes.csv`` row is a finished episode that a resumed run may keep."""
    try:
        timed = math.isfinite(float(row["wall_time_s"]))
    except (TypeError, ValueError):
        timed = False
    has_log = row["log"] == log_name and (not log_name or (out / log_name).is_file())
    return timed and row["error"] == "" and has_log


class EpisodeAppender:
    """``episodes.csv`` while the episodes run: the rows kept from before, then a line per finished episode."""

    def __init__(self, path: Path, rows: list[dict[str, Any]]) -> None:
        """Write ``path`` afresh with its header and ``rows``."""
        from drillgym.eval.bench.report import episodes_frame

        self.path = path
        episodes_frame(rows).to_csv(path, index=False)

    def __call__(self, row: dict[str, Any]) -> None:
        """Append one finished episode's row (one write: a crash cuts at most that line)."""
        from drillgym.eval.bench.episode_line import episode_line

        with self.path.open("a") as f:
            f.write(episode_line(row))


def resume_command(args: argparse.Namespace) -> str:
    """The ``drillgym bench ... --resume`` command that finishes this run."""
    argv = ["drillgym", "bench", "--suite", args.suite, "--controllers", args.controllers]
    argv += ["--cell", getattr(args, "cell", "ideal"), "--seeds", str(args.seeds), "--out", str(args.out)]
    if getattr(args, "reality", ""):
        argv += ["--reality", args.reality]
    if args.workers != 1:
        argv += ["--workers", str(args.workers)]
    if getattr(args, "reference", None):
        argv += ["--reference", args.reference]
    if args.no_logs:
        argv.append("--no-logs")
    if getattr(args, "address", None):
        argv += ["--address", args.address]
    elif getattr(args, "ray", False):
        argv.append("--ray")
    return shlex.join([*argv, "--resume"])


def run(args: argparse.Namespace) -> int:
    """Entry point of ``drillgym bench`` (bad arguments raise ``ValueError`` for the CLI's one-line error)."""
    specs = check_arguments(args)
    from drillgym.eval.bench.report import few_seeds_warning, write_report
    from drillgym.eval.bench.suites import suite_scenarios

    out: Path = args.out
    scenarios = suite_scenarios(args.suite)
    effects = cell_effects_spec(getattr(args, "cell", "ideal"))
    jobs = _jobs(args, specs, scenarios, effects)
    done = finished_rows(out, jobs) if getattr(args, "resume", False) else []
    if getattr(args, "overwrite", False):
        clear_previous_run(out)
    (out if args.no_logs else out / "logs").mkdir(parents=True, exist_ok=True)
    (out / "errors.log").unlink(missing_ok=True)  # a resumed run's, rewritten if an episode fails again
    (out / RUN_JSON).write_text(json.dumps(run_settings(args, specs), indent=1) + "\n")
    finished = {(r["suite"], r["scenario"], r["controller"], r["seed"]) for r in done}
    todo = [job for job in jobs if job.key not in finished]
    try:
        rows = _run_episodes(args, todo, done)
    except KeyboardInterrupt:
        print(
            f"drillgym bench: {out / 'episodes.csv'} keeps the {_count_rows(out / 'episodes.csv')} of {len(jobs)} "
            f"episodes that finished; to run the rest and write the report:\n  {resume_command(args)}",
            file=sys.stderr,
        )
        raise
    reference = reference_spec(specs, getattr(args, "reference", None))
    report = write_report(out, rows, args.suite, [s.name for s in scenarios], specs, args.seeds, reference)
    notes = []
    if effects:
        notes.append(f"Cell: {args.cell} (unmodelled effects on: `{effects}`; docs/explain-paper.md).")
    if getattr(args, "reality", ""):
        notes.append(f"Reality: `{args.reality}` (reality-library effects on every episode; docs/diagnosis.md).")
    if notes:
        summary = out / "summary.md"
        summary.write_text("\n".join(notes) + "\n\n" + summary.read_text())
    print((out / "summary.md").read_text())
    if report.verdicts:
        print(f"Verdicts vs `{reference}` (scenario {report.verdict_scenario}; lower is better for every metric):")
        print("\n".join(f"  {line}" for line in report.verdicts))
    print(
        f"Results: {out.resolve()}/ (episodes.csv, summary.csv, paired.csv, summary.md, plots{', logs/' * (not args.no_logs)})"
    )
    warning = few_seeds_warning(args.seeds)
    if warning:
        print(f"drillgym bench: warning: {warning}", file=sys.stderr)
    return _report_failures(report.episodes, out)


def _jobs(args: argparse.Namespace, specs: list[str], scenarios: list[Any], effects: str) -> list[EpisodeJob]:
    """Every episode of the run: scenario × controller × seed, each with its log (none with ``--no-logs``)."""
    from drillgym.eval.bench.episode import EpisodeJob

    jobs = []
    for sc in scenarios:
        for spec in specs:
            for seed in range(args.seeds):
                name = f"logs/{args.suite}__{sc.name}__{controller_label(spec)}__seed{seed}.parquet"
                log = None if args.no_logs else args.out / name
                fx = sc.episode_effects(seed, effects)  # the --cell's, then the scenario's
                jobs.append(
                    EpisodeJob(
                        args.suite, sc.name, sc.kwargs, spec, seed, log, "" if log is None else name, fx,
                        getattr(args, "reality", ""),
                    )
                )  # fmt: skip
    return jobs


def _run_episodes(args: argparse.Namespace, todo: list[EpisodeJob], done: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Run ``todo`` after ``done``, each row appended to ``episodes.csv`` as it comes; every row, in any order."""
    append = EpisodeAppender(args.out / "episodes.csv", done)
    if not todo:
        return done
    if getattr(args, "ray", False) or getattr(args, "address", None):  # the Ray run streams episodes.csv itself
        from drillgym.eval.scale.bench_ray import run_jobs_ray

        cpus = args.workers if args.workers > 1 else None  # a local Ray's CPUs (default: the machine's)
        return run_jobs_ray(
            todo, args.out, args.address, desc=f"bench {args.suite}", num_cpus=cpus, done_rows=done
        ).rows
    return done + run_jobs(todo, args.workers, desc=f"bench {args.suite}", on_row=append)


def _count_rows(path: Path) -> int:
    """Rows of a CSV file; 0 if it is missing or empty."""
    try:
        return len(read_episodes_csv(path))
    except (OSError, ValueError):
        return 0


def _report_failures(episodes: pd.DataFrame, out: Path) -> int:
    """List the failed episodes on stderr: 1 if there are any, else 0."""
    failed = episodes[episodes["error"].fillna("") != ""]
    if len(failed):
        print(f"drillgym bench: {len(failed)} of {len(episodes)} episodes failed:", file=sys.stderr)
        for r in failed.itertuples(index=False):
            print(f"  {r.scenario} {r.controller} seed {r.seed}: {r.error}", file=sys.stderr)
        print(f"  tracebacks: {out / 'errors.log'}", file=sys.stderr)
        return 1
    return 0
