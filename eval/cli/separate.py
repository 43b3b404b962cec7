"""``drillgym separate --diagnosis DIR --real LOGS --out OUT``: which holes would tell the named model from the rest.

For a diagnosis that named a model while another with other physics was "not ruled out", simulate a few of the
logged holes at other feeds and angles with each model playing the reality and say where the other is furthest off
(:mod:`drillgym.eval.diagnosis.separate`). A separation is a record: an ``--out`` that holds one is refused.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from drillgym.envs.errors import UserError
from drillgym.eval.cli.bench import previous_run

RECORD_FILES = ("separation.json", "separation.md", "separation.png")
"""What ``drillgym separate`` writes into its ``--out``."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    from drillgym.eval.diagnosis.separate import BETAS_DEG, FEED_FACTORS, HOLES

    parser.add_argument(
        "--diagnosis", required=True, type=Path, help="a diagnosis: its folder (diagnosis.json inside) or the file"
    )
    parser.add_argument("--real", required=True, type=Path, help="the logs it diagnosed (the holes' scenarios)")
    parser.add_argument("--out", required=True, type=Path, help="output folder: separation.json, .md, .png")
    parser.add_argument(
        "--feed-factors",
        default=",".join(f"{f:g}" for f in FEED_FACTORS),
        help="feeds to try, as factors of each logged hole's feed (default: %(default)s; 1 = as logged)",
    )
    parser.add_argument(
        "--betas-deg",
        default=",".join(f"{b:g}" for b in BETAS_DEG),
        help="interaction angles to try, each for every hole at its logged feed (default: %(default)s; '' for none)",
    )
    parser.add_argument(
        "--holes", type=int, default=HOLES, help="logged holes re-simulated per change and direction (default: 3)"
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated holes' noise and specimens")
    parser.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="processes (default: all cores; the rows do not change)",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-figure", action="store_true", help="skip separation.png")


def _numbers(text: str, option: str, example: str) -> list[float]:
    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError as e:
        raise UserError(f"{option} {text!r}: comma-separated numbers, e.g. {example}") from e
    if len(set(values)) != len(values):
        raise UserError(f"{option} {text!r} repeats a value")
    return values


def _diagnosis(path: Path) -> dict:
    file = path / "diagnosis.json" if path.is_dir() else path
    try:
        return json.loads(file.read_text())
    except FileNotFoundError as e:
        raise UserError(f"--diagnosis {path}: no diagnosis.json there") from e
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise UserError(f"--diagnosis {file}: not a diagnosis.json ({e})") from e


def run(args: argparse.Namespace) -> int:
    """Check, simulate, write."""
    from tqdm import tqdm

    from drillgym.eval.diagnosis.episodes import load_episodes
    from drillgym.eval.diagnosis.separate import changes, separate
    from drillgym.eval.diagnosis.separate_report import separation_line, write_separation
    from drillgym.eval.progress import bar_size

    if args.out.exists() and not args.out.is_dir():
        raise UserError(f"--out {args.out} exists and is not a folder")
    found = previous_run(args.out, RECORD_FILES, ())
    if found:
        raise UserError(f"{args.out} holds a previous separation ({', '.join(found)}): pass another --out")
    if args.holes < 1:
        raise UserError(f"--holes={args.holes} must be >= 1")
    if args.workers < 1:
        raise UserError(f"--workers={args.workers} must be >= 1")
    grid = changes(
        _numbers(args.feed_factors, "--feed-factors", "0.25,0.5,1,2"), _numbers(args.betas_deg, "--betas-deg", "0,40")
    )
    diagnosis = _diagnosis(args.diagnosis)
    episodes, skipped = load_episodes(args.real)
    for s in skipped:
        print(f"skipped {s}", file=sys.stderr)
    bar_args = {"file": sys.stderr, "disable": True if args.no_progress else None, **bar_size(sys.stderr)}
    with tqdm(desc="separate", unit="job", **bar_args) as bar:

        def tick(jobs: int) -> None:
            bar.total = jobs
            bar.update(1)

        result = separate(diagnosis, episodes, grid, args.holes, args.seed, progress=tick, workers=args.workers)
    paths = write_separation(result, args.out, figure=not args.no_figure)
    for pair in result["pairs"]:
        print(f"{result['named']} against {pair['other']}: {separation_line(pair)}")
    print(f"wrote {paths['json']} and {paths['report']}")
    return 0
