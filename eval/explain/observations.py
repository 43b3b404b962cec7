"""Li et al. 2023's reported runs as a real cell's data: values, the subset a fit may see, and their scatter.

Three runs of the paper scenario: uncompensated (``none``), li2023 at KP 1 (``kp1``) and at KP 4 (``kp4``).
Li reports four numbers for ``none`` and ``kp4`` and only the deviation for ``kp1``. In the primary fold the
calibration subset is ``none`` and ``kp1``; ``kp4`` is held out: it is read only to score predictions, never by a
fit. Cross-validation (:data:`FOLDS`) holds out each run in turn, with the same rule.

Each value is a single trial, so its scatter is assumed (:func:`sigma`): the simulator's own seed-to-seed
standard deviation of that number, plus a relative allowance for what the simulator does not vary (specimen
to specimen, more than the sim's 5 % hardness; set-up to set-up), plus an absolute floor for how finely the
number is measured. Units: mm and N, as Li reports them (the metrics' own names carry the unit).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from drillgym.envs.errors import UserError
from drillgym.eval.reproduce.paper import LI2023_COMPENSATED, LI2023_UNCOMPENSATED

RUNS = ("none", "kp1", "kp4")
"""Li's three runs: uncompensated, li2023 KP 1, li2023 KP 4."""
CALIBRATION_RUNS = ("none", "kp1")
"""What a fit may see (the primary fold)."""
HELD_OUT_RUN = "kp4"
"""What only the predictions are scored on (the primary fold)."""
FOLDS = ("kp4", "none", "kp1")
"""Cross-validation: the held-out run of each fold, every run in turn, the primary fold first. A fold fits on the
other two runs and predicts its own; the KP 1 fold can score one number only (Li reports only KP 1's deviation)."""
METRICS = ("deviation_mean_mm", "lateral_force_max_n", "lateral_force_stable_n", "hole_offset_mm")
"""The summary metrics Li reports (sim metric names)."""

REL_ALLOWANCE = 0.15
"""Relative scatter of a single trial beyond the simulator's seeds: cortical bone's cutting forces vary by
10-20 % between specimens and sites of one bone (the simulator draws only 5 %), and a compensated run also
inherits the scatter of the trial hole its force model was fitted to."""
FLOORS = {
    "deviation_mean_mm": 0.03,
    "lateral_force_max_n": 0.05,
    "lateral_force_stable_n": 0.05,
    "hole_offset_mm": 0.05,
}
"""Absolute floors: a mean over a run of an optical tracker's lateral reading (0.03 mm after averaging a
~0.1 mm single-frame noise), a filtered F/T lateral force (0.05 N: resolution plus a tare at the 0.01 N
level), a hole centre measured on a section (0.05 mm)."""


def li_values() -> dict[str, dict[str, float]]:
    """Every number Li reports, by run and metric (read from :mod:`drillgym.eval.reproduce.paper` at call time)."""
    kp4 = {k: float(LI2023_COMPENSATED[k]) for k in METRICS}
    return {
        "none": {k: float(LI2023_UNCOMPENSATED[k]) for k in METRICS},
        "kp1": {"deviation_mean_mm": float(LI2023_COMPENSATED["deviation_mean_mm_kp1"])},
        "kp4": kp4,
    }


def calibration_runs(held_out: str = HELD_OUT_RUN) -> tuple[str, ...]:
    """The runs a fit may see when ``held_out`` is held out (the other two, in :data:`RUNS` order).

    Raises:
        ValueError: ``held_out`` is not one of :data:`RUNS`.
    """
    if held_out not in RUNS:
        raise UserError(f"unknown held-out run {held_out!r}; choose from {list(RUNS)}")
    return tuple(run for run in RUNS if run != held_out)


def calibration_targets(held_out: str = HELD_OUT_RUN) -> dict[tuple[str, str], float]:
    """``(run, metric) -> value`` of the fold's calibration runs only (no held-out number is in it)."""
    values = li_values()
    return {(run, k): v for run in calibration_runs(held_out) for k, v in values[run].items()}


def held_out_targets(held_out: str = HELD_OUT_RUN) -> dict[str, float]:
    """The held-out run's numbers (what Li reports of it), for scoring predictions only."""
    calibration_runs(held_out)
    return dict(li_values()[held_out])


def check_calibration_only(targets: Mapping[tuple[str, str], float], held_out: str = HELD_OUT_RUN) -> None:
    """Refuse targets that hold anything but the fold's calibration runs (a held-out number must never be fitted).

    Raises:
        ValueError: a key of another run.
    """
    allowed = calibration_runs(held_out)
    bad = sorted({run for run, _ in targets} - set(allowed))
    if bad:
        raise ValueError(f"a fit may only see the calibration runs {allowed}, got {bad}")


def sigma(metric: str, value: float, seed_sd: float) -> float:
    """Assumed standard deviation of one trial's ``metric`` at ``value`` (same unit), given the sim's seed SD."""
    if metric not in FLOORS:
        raise UserError(f"unknown metric {metric!r}; choose from {list(FLOORS)}")
    return math.sqrt(seed_sd**2 + (REL_ALLOWANCE * value) ** 2 + FLOORS[metric] ** 2)
