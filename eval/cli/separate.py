"""``drillgym separate --diagnosis DIR --real LOGS --out OUT``: which holes would tell the named model from the rest.

For a diagnosis that named a model while another with other physics was "not ruled out", simulate a few of the
logged holes at other feeds with each model playing the reality and say at which feed the other is furthest off
(:mod:`drillgym.eval.diagnosis.separate`). A separation is a record: an ``--out`` that holds one is refused.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from drillgym.envs.errors import UserError
from drillgym.eval.cli.bench import previous_run

RECORD_FILES = ("separation.json", "separation.md", "separation.png")
"""What ``drillgym separate`` writes into its ``--out``."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    from drillgym.eval.diagnosis.separate import FEED_FACTORS, HOLES

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
    parser.add_argument("--holes", type=int, default=HOLES, help="logged holes re-simulated per feed (default: 3)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated holes' noise and specimens")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--no-figure", action="store_true", help="skip separation.png")


def _factors(text: str) -> list[float]:
    try:
        factors = [float(x) for x in text.split(",") if x.strip()]
    except ValueError as e:
        raise UserError(f"--feed-factors {text!r}: comma-separated numbers, e.g. 0.25,0.5,1,2") from e
    if not factors:
        raise UserError("--feed-factors: give at least one factor")
    if len(set(factors)) != len(factors):
        raise UserError(f"--feed-factors {text!r} repeats a factor")
    return factors


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
    from drillgym.eval.diagnosis.separate import check_factors, models_to_separate, pick_holes, separate
    from drillgym.eval.diagnosis.separate_report import separation_line, write_separation

    if args.out.exists() and not args.out.is_dir():
        raise UserError(f"--out {args.out} exists and is not a folder")
    found = previous_run(args.out, RECORD_FILES, ())
    if found:
        raise UserError(f"{args.out} holds a previous separation ({', '.join(found)}): pass another --out")
    if args.holes < 1:
        raise UserError(f"--holes={args.holes} must be >= 1")
    factors = _factors(args.feed_factors)
    diagnosis = _diagnosis(args.diagnosis)
    named, others = models_to_separate(diagnosis)
    episodes, skipped = load_episodes(args.real)
    for s in skipped:
        print(f"skipped {s}", file=sys.stderr)
    check_factors(factors, pick_holes(episodes, args.holes))
    total = 2 * len(factors) * len(others)
    with tqdm(total=total, desc="separate", unit="feed", disable=True if args.no_progress else None) as bar:
        result = separate(diagnosis, episodes, factors, args.holes, args.seed, progress=lambda: bar.update(1))
    paths = write_separation(result, args.out, figure=not args.no_figure)
    for pair in result["pairs"]:
        print(f"{named.name} against {pair['other']}: {separation_line(pair)}")
    print(f"wrote {paths['json']} and {paths['report']}")
    return 0
