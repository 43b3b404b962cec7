"""``drillgym validate-forces``: the force model against published bone-drilling measurements (:mod:`drillgym.eval.external`)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from drillgym.envs.errors import UserError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument(
        "--out", type=Path, required=True, help="output folder (validation.json, validation.md, figures)"
    )
    parser.add_argument(
        "--studies",
        default="all",
        help="comma-separated study keys to run (default all: macavelia2012, orelaja2020, abjs_feed)",
    )


def run(args: argparse.Namespace) -> int:
    """Entry point: writes the validation into a new folder (an existing, non-empty one is refused)."""
    from drillgym.eval.external.report import markdown, plot_study
    from drillgym.eval.external.studies import SOURCES
    from drillgym.eval.external.validate import validate

    studies = tuple(SOURCES) if args.studies.strip() == "all" else tuple(x.strip() for x in args.studies.split(","))
    unknown = [x for x in studies if x not in SOURCES]
    if unknown or not studies:
        raise UserError(
            f"--studies: unknown study {unknown or args.studies!r}; choose from {', '.join(SOURCES)} or all"
        )
    out: Path = args.out
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UserError(f"--out {out} exists and is not an empty folder: a validation's record is never overwritten")
    result = validate(studies)
    out.mkdir(parents=True, exist_ok=True)
    figures = {s: plot_study(result, s, out / f"{s}.png") for s in dict.fromkeys(x["study"] for x in result["series"])}
    (out / "validation.json").write_text(json.dumps(result, indent=2) + "\n")
    md = markdown(result, figures)
    (out / "validation.md").write_text(md)
    print(md)
    print(f"Results: {out / 'validation.json'} and {out / 'validation.md'}")
    return 0
