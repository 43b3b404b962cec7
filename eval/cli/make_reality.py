"""``drillgym make-reality``: real-schema episode logs from the simulator with unmodelled effects on."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    from drillgym.eval.diagnosis.reality.library import REALITY_EFFECTS

    parser.add_argument(
        "--effects",
        required=True,
        help=f"NAME[:PARAM=VALUE,...][+NAME...] or 'none'; effects: {', '.join(REALITY_EFFECTS)}",
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
