"""``drillgym calibrate``: calibrate the entry mechanics on the uncompensated paper run (:mod:`drillgym.eval.calibration.screen`)."""

from __future__ import annotations

import argparse
import csv
from itertools import product
from pathlib import Path
from typing import Any

from drillgym.envs.cell_params import CellParams
from drillgym.envs.errors import UserError
from drillgym.eval.calibration.calibrate import (
    LI2023_CHECKS,
    METRICS,
    EntryStructure,
)
from drillgym.eval.calibration.screen import evaluate_all
from drillgym.eval.cli.bench import refuse_previous_record
from drillgym.eval.reproduce.paper import LI2023_UNCOMPENSATED


def comma_floats(text: str) -> list[float]:
    """``"0.1,0.2"`` -> ``[0.1, 0.2]`` (an argparse type: a clear error for anything else)."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}") from e
    if not values:
        raise argparse.ArgumentTypeError("expected at least one number")
    return values


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Command-line options."""
    d = CellParams()
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument(
        "--overwrite", action="store_true", help="replace a previous record in --out (without it, one is refused)"
    )
    parser.add_argument(
        "--skid-relief", type=comma_floats, default=[d.skid_relief], help="comma list (default: shipped)"
    )
    parser.add_argument(
        "--lateral-cut-resistance-n", type=comma_floats, default=[d.lateral_cut_resistance_n], help="K_lat values, N"
    )
    parser.add_argument("--guidance-exponent", type=comma_floats, default=[d.guidance_exponent], help="comma list")
    parser.add_argument(
        "--wall-guidance-floor", type=comma_floats, default=[d.wall_guidance_floor], help="comma list, each in (0, 1]"
    )
    parser.add_argument("--wall-length-mm", type=comma_floats, default=[d.wall_length_m * 1e3], help="comma list, mm")
    parser.add_argument(
        "--effects",
        default="",
        help="unmodelled effects switched on in the cell for the fit and the predictions, e.g. the Li cell's "
        "joint_friction:coulomb_rad=0.000417 (default: none)",
    )
    parser.add_argument("--seeds", type=int, default=3, help="seeds of the li2023 predictions (default 3)")
    parser.add_argument("--workers", type=int, default=1, help="parallel processes (default 1)")


def _markdown(rows: list[dict[str, Any]]) -> str:
    head = (
        "| relief | K_lat (N) | exponent | wall floor | wall (mm) | lateral scale | stick-out (mm) | none: dev / peak / stable / hole "
        "| li2023 KP 4 | KP 1 | offline only | checks |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n"
    )

    def quad(r: dict[str, Any], p: str) -> str:
        return " / ".join(f"{r[f'{p}_{k}']:.3g}" for k in METRICS)

    lines = []
    for r in rows:
        failed = [k for k in LI2023_CHECKS if not r[k]]
        lines.append(
            f"| {r['skid_relief']:g} | {r['lateral_cut_resistance_n']:g} | {r['guidance_exponent']:g} "
            f"| {r['wall_guidance_floor']:g} | {1e3 * r['wall_length_m']:g} "
            f"| {r['lateral_scale']:.3f}{'' if r['converged'] else ' (not converged)'} | {r['stickout_mm']:.1f} "
            f"| {quad(r, 'none')} | {quad(r, 'kp4')} | {quad(r, 'kp1')} | {quad(r, 'offline')} "
            f"| {'all pass' if not failed else 'fails: ' + ', '.join(failed)} |"
        )
    li = LI2023_UNCOMPENSATED
    intro = (
        "# Entry-mechanics calibration and li2023 predictions\n\n"
        f"Each row: lateral scale and stick-out fitted to Li's uncompensated deviation ({li['deviation_mean_mm']:g} mm) "
        f"and peak force ({li['lateral_force_max_n']:g} N); stable-stage force (paper {li['lateral_force_stable_n']:g} N) "
        f"and hole offset ({li['hole_offset_mm']:g} mm) are not fitted. li2023's model is "
        "refitted to the calibrated uncompensated F/T force. Metrics: mean tip deviation (mm) / peak lateral "
        "force (N) / stable-stage force (N) / hole offset (mm), means over the seeds. Checks: "
        "KP ordering, force and hole-offset falls need the 95 % CI of the paired difference to exclude 0.\n\n"
    )
    return intro + head + "\n".join(lines) + "\n"


def run(args: argparse.Namespace) -> int:
    """Calibrate every combination, write the table, print where it is."""
    from tqdm import tqdm

    if args.seeds < 1 or args.workers < 1:
        raise UserError("--seeds and --workers must be >= 1")
    if args.effects:
        from drillgym.envs.effects import build_effects

        build_effects(args.effects)  # a bad spec is an error before any work
    refuse_previous_record(
        args.out, ("calibration.csv", "calibration.md", "calibration.png"), args.overwrite, "calibration"
    )
    grid = [
        EntryStructure(r, k, g, f, w * 1e-3)
        for r, k, g, f, w in product(
            args.skid_relief,
            args.lateral_cut_resistance_n,
            args.guidance_exponent,
            args.wall_guidance_floor,
            args.wall_length_mm,
        )
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    rows: list[dict[str, Any]] = [{} for _ in grid]
    csv_path = args.out / "calibration.csv"
    writer = None
    with (
        csv_path.open("w", newline="") as fh,
        tqdm(total=len(grid), desc="calibrate", unit="model", disable=None) as bar,
    ):
        for i, row in evaluate_all(grid, args.seeds, args.workers, args.effects):
            if writer is None:
                writer = csv.DictWriter(fh, fieldnames=list(row))
                writer.writeheader()
            writer.writerow(row)
            fh.flush()
            rows[i] = row  # the table keeps the grid's order
            bar.update(1)
    from drillgym.eval.calibration.plot import plot_screen

    plot_screen(rows, args.out / "calibration.png")
    md = _markdown(rows) + "\n![li2023 predictions of every structure](calibration.png)\n"
    (args.out / "calibration.md").write_text(md)
    print(md)
    print(f"Results: {csv_path}, {args.out / 'calibration.md'} and {args.out / 'calibration.png'}")
    return 0
