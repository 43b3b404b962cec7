"""Acceptance rules of a trained residual policy, checked for every training seed alone.

Every training seed is checked on paired episodes (:func:`drillgym.eval.learning.seed_stats.paired_diff`:
policy minus baseline on the same ``(scenario, seed)``, Student-t 95 % CI; negative is better) against the best
classical baseline and the paper's reference; the rules are :data:`RULES` and ``passes`` is all of them.
:func:`drillgym.eval.learning.best_classical.choose_best_classical` applies the same rules to classical
candidates.
"""

from __future__ import annotations

import math
from typing import Any

import pandas as pd

from drillgym.eval.learning.seed_stats import (
    DEVIATION,
    FORCE,
    POLICY,
    TIME,
    _natural,
    _paired,
    normalise_episodes,
)

PAPER = "paper"
HELDOUT = "heldout"
GENERALISATION = "generalisation"
REFERENCE_GAIN_PCT = -30.0
"""``beats_reference_30pct``: the paper deviation must be at least 30 % below the reference's."""
TIME_SLACK_PCT = 30.0
"""``time_ok``: the paper drill time may be at most 30 % above the best baseline's."""
RULES = {
    "paper_better": "paper deviation paired diff vs the best baseline: CI high < 0",
    "paper_force_ok": "paper peak lateral force paired diff vs the best baseline: CI low <= 0 (not significantly higher)",
    "generalisation_better": "generalisation deviation paired diff vs the best baseline, pooled over plans: CI high < 0",
    "heldout_better": "heldout deviation paired diff vs the best baseline, pooled over scenarios: mean < 0",
    "heldout_none_worse": "no heldout scenario with a deviation significantly worse than the best baseline (CI low > 0)",
    "beats_reference_30pct": "paper deviation at most -30 % relative to the reference",
    "time_ok": "paper drill time at most +30 % relative to the best baseline",
}
"""The acceptance rules of :func:`seed_checks`; ``passes`` is all of them."""
_DIFF_FIELDS = ("mean", "low", "high", "n", "dropped")


def _relative_pct(diff: dict[str, float]) -> float:
    """``100 * (policy_mean / baseline_mean - 1)`` over the pairs of a :func:`paired_diff`, NaN without any."""
    base = diff["baseline_mean"]
    if not math.isfinite(base) or base == 0.0:
        return math.nan
    return 100.0 * (diff["policy_mean"] / base - 1.0)


def _prefixed(prefix: str, diff: dict[str, float]) -> dict[str, float]:
    return {f"{prefix}_{k}": diff[k] for k in _DIFF_FIELDS}


CHECK_COLUMNS = (
    "run",
    *(f"paper_deviation_{k}" for k in _DIFF_FIELDS),
    *(f"paper_force_{k}" for k in _DIFF_FIELDS),
    "paper_deviation_vs_reference_pct",
    *(f"generalisation_deviation_{k}" for k in _DIFF_FIELDS),
    *(f"heldout_deviation_{k}" for k in _DIFF_FIELDS),
    "heldout_worse_scenarios",
    "paper_time_vs_best_pct",
    *RULES,
    "passes",
    "notes",
)
"""Columns of :func:`seed_checks`."""


def run_checks(frame: pd.DataFrame, run: str, best: str, reference: str) -> dict[str, Any]:
    """One run's row of :func:`seed_checks` (``frame`` normalised by :func:`normalise_episodes`)."""
    suites = set(frame["suite"])
    row: dict[str, Any] = {"run": run}
    paper = _paired(frame, run, POLICY, best, PAPER, DEVIATION)
    force = _paired(frame, run, POLICY, best, PAPER, FORCE)
    row |= _prefixed("paper_deviation", paper) | _prefixed("paper_force", force)
    row["paper_deviation_vs_reference_pct"] = _relative_pct(_paired(frame, run, POLICY, reference, PAPER, DEVIATION))
    general = _paired(frame, run, POLICY, best, GENERALISATION, DEVIATION)
    row |= _prefixed("generalisation_deviation", general)
    held = _paired(frame, run, POLICY, best, HELDOUT, DEVIATION)
    row |= _prefixed("heldout_deviation", held)
    scenarios = sorted(set(frame.loc[frame["suite"] == HELDOUT, "scenario"]))
    row["heldout_worse_scenarios"] = [
        sc for sc in scenarios if _paired(frame, run, POLICY, best, HELDOUT, DEVIATION, sc)["low"] > 0.0
    ]
    row["paper_time_vs_best_pct"] = _relative_pct(_paired(frame, run, POLICY, best, PAPER, TIME))
    row["paper_better"] = bool(paper["high"] < 0.0)
    row["paper_force_ok"] = bool(force["low"] <= 0.0)
    row["generalisation_better"] = bool(general["high"] < 0.0)
    row["heldout_better"] = bool(held["mean"] < 0.0)
    row["heldout_none_worse"] = bool(HELDOUT in suites and held["n"] > 0 and not row["heldout_worse_scenarios"])
    row["beats_reference_30pct"] = bool(row["paper_deviation_vs_reference_pct"] <= REFERENCE_GAIN_PCT)
    row["time_ok"] = bool(row["paper_time_vs_best_pct"] <= TIME_SLACK_PCT)
    row["passes"] = all(row[rule] for rule in RULES)
    row["notes"] = "; ".join(_notes(suites, {PAPER: paper, GENERALISATION: general, HELDOUT: held}))
    return row


def _notes(suites: set[str], diffs: dict[str, dict[str, float]]) -> list[str]:
    notes = []
    for suite, diff in diffs.items():
        if suite not in suites:
            notes.append(f"{suite} suite missing: its checks are NaN/False")
        elif diff["n"] == 0:
            notes.append(f"no paired {suite} deviation episodes: its checks are NaN/False")
        if diff["dropped"]:
            notes.append(f"{suite}: {int(diff['dropped'])} failed or unpaired deviation pairs dropped")
    return notes


def seed_checks(episodes: pd.DataFrame, best_baseline: str, reference: str = "li2023") -> pd.DataFrame:
    """Check every training run of the policy alone against the best baseline and the paper's reference.

    All differences are paired (:func:`paired_diff`, policy minus baseline, Student-t 95 % CI); negative is
    better. The acceptance rules are in :data:`RULES`: the paper deviation significantly lower than the best
    baseline's (CI high < 0), the paper peak lateral force not significantly higher (CI low <= 0), the deviation
    over the generalisation suite's plans (inside the training ranges, never trained on) significantly lower
    (pooled CI high < 0), the heldout
    deviation lower on average over all heldout scenarios (pooled mean < 0), no heldout scenario significantly
    worse (CI low > 0), the paper deviation at least 30 % below the reference's, and the paper drill time at most
    30 % above the best baseline's; ``passes`` is all of them. A missing suite gives NaN figures and False checks,
    said in ``notes``.

    Args:
        episodes: one row per episode; the policy's rows have ``controller == "policy"`` and their run in ``run``.
        best_baseline: the strongest baseline's label, e.g. ``"li2023_tuned"``.
        reference: the paper's compensator's label, ``"li2023"``.

    Returns:
        One row per run (natural order) with the columns :data:`CHECK_COLUMNS`: ``*_mean/low/high`` are paired
        differences in mm (deviation) or N (force), ``*_n`` the pairs used, ``*_dropped`` the pairs dropped,
        ``*_pct`` relative changes in % (``100 * (mean_policy / mean_baseline - 1)`` over the paired episodes),
        ``heldout_worse_scenarios`` a list of scenario names, the rule columns and ``passes`` booleans.
    """
    frame = normalise_episodes(episodes)
    runs = sorted(set(frame.loc[frame["controller"] == POLICY, "run"]), key=_natural)
    rows = [run_checks(frame, run, best_baseline, reference) for run in runs]
    return pd.DataFrame(rows, columns=list(CHECK_COLUMNS))
