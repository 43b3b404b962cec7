"""``drillgym make-reality``: real-schema episode logs from the simulator with unmodelled effects on."""

from __future__ import annotations

import argparse
from pathlib import Path

from drillgym.eval.cli import HelpFormatter


class _Formatter(HelpFormatter, argparse.RawDescriptionHelpFormatter):
    """The commands' formatter, keeping the epilog's lines (the effects' parameter list) as written."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments; the epilog lists every reality effect's parameters (from the effect registry)."""
    from drillgym.eval.diagnosis.reality.library import REALITY_EFFECTS, parameters_help

    parser.formatter_class = _Formatter
    parser.epilog = parameters_help()
    parser.add_argument(
        "--effects",
        required=True,
        help=f"NAME:PARAM=VALUE[,...][+NAME...] or 'none'; each effect needs a parameter that switches it on (* below); "
        f"effects: {', '.join(REALITY_EFFECTS)}",
    )
    parser.add_argument("--episodes", type=int, default=20, help="episodes to write (default 20)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the scenarios, controllers, noise and specimens")
    parser.add_argument("--out", required=True, type=Path, help="folder for episode_NNN.parquet")
    parser.add_argument(
        "--truth",
        type=Path,
        default=None,
        help="where to write what was switched on (default: OUT.truth.json, beside OUT)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing logs")


def run(args: argparse.Namespace) -> int:
    """Generate the logs and the truth file."""
    from drillgym.eval.diagnosis.reality.generate import make_reality, write_truth

    truth = make_reality(args.effects, args.episodes, args.seed, args.out, overwrite=args.overwrite)
    out = Path(args.out)
    path = write_truth(truth, args.truth or out.with_name(out.name + ".truth.json"))
    print(f"wrote {args.episodes} episode logs to {out} (source: real); truth in {path}")
    return 0
