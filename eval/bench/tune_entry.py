"""Tune a slow entry on top of a base controller, on the paper and sweep suites.

The command is :mod:`drillgym.eval.cli.tune_entry`.

A grid of entry feed multipliers × entry depths (:mod:`drillgym.controllers.feed_schedule`), and optionally × the
base's proportional gain (``--kps``: a slower entry changes how hard the base should push), is run on every
scenario of the tuning suites (default ``paper`` and ``sweep``, never ``heldout``, which stays for
judging learnt policies) over the same seeds as the base alone. The rule that picks the best schedule
is fixed before running:

* objective: the mean deviation, averaged over the suites (each suite's scenarios pooled, each suite
  weighing the same), lowest wins;
* constraints, each against the base on the same episodes: the peak lateral force of every suite not
  higher (pooled mean), and the drill time on the paper suite at most ``--max-time-increase`` longer.

Outputs in ``--out``: ``episodes.csv`` (every episode), ``grid.csv`` (one row per candidate),
``tune_entry.md`` and ``tune_entry.png`` (objective over the grid, the chosen cell marked).
"""

from __future__ import annotations

from typing import Any

import pandas as pd

TUNING_SUITES = ("paper", "sweep")


def gain_settings(kps: list[float] | None = None, y_gains: list[float] | None = None) -> list[str]:
    """The base's gain settings tried, as spec fields ending in a comma (kp-major order; ``[""]`` for none)."""
    kp_items = [f"kp={k:g}," for k in kps] if kps else [""]
    y_items = [f"y_gain={y:g}," for y in y_gains] if y_gains else [""]
    return [k + y for k in kp_items for y in y_items]


def candidate_specs(
    base: str,
    scales: list[float],
    depths_mm: list[float],
    kps: list[float] | None = None,
    y_gains: list[float] | None = None,
) -> list[str]:
    """The base alone, then the base with each (multiplier, depth) schedule, as controller specs.

    With ``kps`` and/or ``y_gains`` every schedule is tried at each of these gain settings (kp-major order).
    """
    sep = "," if ":" in base else ":"
    gains = gain_settings(kps, y_gains)
    return [base] + [
        f"{base}{sep}{g}entry_feed_scale={s:g},entry_depth_mm={d:g}" for g in gains for s in scales for d in depths_mm
    ]


def grid_table(episodes: pd.DataFrame, base: str, suites: list[str], max_time_increase: float) -> pd.DataFrame:
    """One row per candidate: per-suite pooled means, the objective, the constraints, ``feasible``."""
    per = episodes.groupby(["controller", "suite"])[["deviation_mean_mm", "lateral_force_max_n", "drill_time_s"]]
    means = per.mean()
    rows = []
    for spec in episodes["controller"].unique():
        row: dict[str, Any] = {"controller": spec}
        for suite in suites:
            for metric in ("deviation_mean_mm", "lateral_force_max_n", "drill_time_s"):
                row[f"{suite}_{metric}"] = float(means.loc[(spec, suite), metric])
        rows.append(row)
    grid = pd.DataFrame(rows).set_index("controller")
    grid["objective_mm"] = grid[[f"{s}_deviation_mean_mm" for s in suites]].mean(axis=1)
    ok = pd.Series(True, index=grid.index)
    reference: dict[Any, Any] = grid.loc[base].to_dict()
    for suite in suites:
        col = f"{suite}_lateral_force_max_n"
        ok &= grid[col] <= float(reference[col]) + 1e-12
    if "paper" in suites:
        ok &= grid["paper_drill_time_s"] <= (1.0 + max_time_increase) * float(reference["paper_drill_time_s"])
    grid["feasible"] = ok
    return grid.reset_index()


def best_candidate(grid: pd.DataFrame) -> str:
    """The feasible candidate with the lowest objective (the base itself is always a candidate)."""
    feasible = grid[grid["feasible"]]
    if feasible.empty:
        feasible = grid.iloc[:1]
    return str(feasible.sort_values("objective_mm").iloc[0]["controller"])
