"""``drillgym demo``: the main job on the embedded default, the paper scenario, end to end.

Runs the paper-reproduction report (calibration, compensators, force model, stiffness identification,
Zhang's analogues), prints its headline table and says where the results are.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument("--out", type=Path, default=Path("results/demo"), help="output folder (default results/demo)")
    parser.add_argument("--seeds", type=int, default=10, help="seeds per compared condition (default 10)")
    parser.add_argument("--quick", action="store_true", help="3 seeds and a short KP sweep")


def run(args: argparse.Namespace) -> int:
    """Run ``drillgym reproduce`` into ``--out``."""
    from drillgym.eval.cli import reproduce

    print("drillgym demo: Li et al. 2023's experiment (beta 30 deg, 0.5 mm/s, 1.5 mm drill) in the simulated cell\n")
    return reproduce.run(args)
