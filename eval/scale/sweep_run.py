"""``drillgym train --sweep SPEC.yaml [--ray] [--address ADDR]``: tune residual training on Ray Tune.

The sweep file is read and checked by :func:`drillgym.training.sweep.load_sweep`; the trials run in
:mod:`drillgym.eval.scale.tune_sweep`.
"""

from __future__ import annotations

import argparse
import sys

from drillgym.training.sweep import load_sweep


def run(args: argparse.Namespace) -> int:
    """``drillgym train --sweep``: check the arguments, run the sweep, export the best policy."""
    try:
        if args.sweep is None:
            raise ValueError("--ray/--address need --sweep SPEC.yaml (a single run trains on one machine)")
        if args.resume:
            raise ValueError("--resume does not apply to --sweep (a failed trial restarts from its checkpoint)")
        from drillgym.eval.scale.cluster import require_ray

        require_ray()
        overrides = {
            k: v
            for k, v in (("total_timesteps", args.timesteps), ("n_envs", args.n_envs), ("seed", args.seed))
            if v is not None
        }
        spec = load_sweep(args.sweep, overrides, args.config)
    except (ValueError, RuntimeError, OSError) as e:
        print(f"drillgym train: error: {e}", file=sys.stderr)
        return 2
    from drillgym.eval.scale.tune_sweep import run_sweep

    try:
        outcome = run_sweep(spec, args.out, args.address, export=args.export)
    except ConnectionError as e:
        print(f"drillgym train: error: {e}", file=sys.stderr)
        return 2
    return 0 if outcome.best is not None else 1
