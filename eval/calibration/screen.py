"""Calibrate the entry mechanics on the uncompensated run and predict li2023.

The command is :mod:`drillgym.eval.cli.calibrate`.

Each combination of the listed structural constants is calibrated (:func:`drillgym.eval.calibration.calibrate.calibrate_entry`)
and its li2023 predictions are run (:func:`drillgym.eval.calibration.calibrate.predict_li2023`). Writes
``DIR/calibration.csv`` (one row per combination, written as each finishes), ``DIR/calibration.md`` and
``DIR/calibration.png`` (:func:`drillgym.eval.calibration.plot.plot_screen`).
With the defaults it reproduces the shipped calibration.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from drillgym.eval.calibration.calibrate import (
    EntryStructure,
    calibrate_entry,
    passes_li2023_checks,
    predict_li2023,
)
from drillgym.eval.pool import run_unordered


def evaluate(structure: EntryStructure, seeds: int, effects: str = "") -> dict[str, Any]:
    """Calibrate one structure and predict li2023 on it (with the cell's ``effects``): one CSV row."""
    cal = calibrate_entry(structure, effects=effects)
    row = cal.row()
    pred = predict_li2023(cal, list(range(seeds)), effects)
    row.update(pred)
    row.update(passes_li2023_checks(pred))
    return row


def evaluate_all(
    grid: list[EntryStructure], seeds: int, workers: int, effects: str = ""
) -> Iterator[tuple[int, dict[str, Any]]]:
    """``(grid index, row)`` as each structure finishes: in this process with one worker, else in a pool."""
    yield from run_unordered(_evaluate_job, [(s, seeds, effects) for s in grid], workers)


def _evaluate_job(job: tuple[EntryStructure, int, str]) -> dict[str, Any]:
    return evaluate(*job)
