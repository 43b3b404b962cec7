"""Which classical controller a learnt policy is judged against: the rule, fixed before judging.

A learnt policy is worth shipping only if it beats what a control engineer would build with the same
knobs. ``li2023_tuned`` (one tuning for every plan) is the default best baseline; a stronger classical
candidate — the gain-scheduling table of ``drillgym tune-table`` (``table:shipped``) — replaces it when it
earns the place by the rules a policy must pass:

* every candidate is checked against the default exactly as a policy is
  (:func:`drillgym.eval.learning.seed_checks.run_checks`: paper deviation significantly lower, paper peak
  force not significantly higher, generalisation deviation significantly lower, heldout pooled lower with no
  heldout scenario significantly worse, paper deviation ≥ 30 % below the reference, drill time ≤ +30 %);
* among the candidates that pass every check, the one with the lowest mean deviation, averaged over the
  judged suites (each suite's episodes pooled, each suite weighing the same), is the best baseline;
* none passes: the default stays.

The rule only reads the baselines' own episodes (never a policy's), so it cannot favour a policy; it can only
make the bar higher.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from drillgym.envs.errors import UserError
from drillgym.eval.learning.seed_checks import RULES, run_checks
from drillgym.eval.learning.seed_stats import DEVIATION, POLICY, _natural, normalise_episodes, paired_diff

RULE = (
    "a classical candidate replaces the default best baseline when it passes every seed-report check against it "
    "(as a policy would); among those that pass, the lowest deviation averaged over the judged suites wins"
)


def choose_best_classical(
    episodes: pd.DataFrame, candidates: Sequence[str], default: str, reference: str = "li2023"
) -> tuple[str, list[dict[str, Any]]]:
    """The best classical baseline among ``candidates`` (plus ``default``), by :data:`RULE`.

    Args:
        episodes: the judge's episodes (policy rows, if any, are ignored).
        candidates: classical controllers' labels as in ``episodes["controller"]``; the default is skipped.
        default: the default best baseline (``li2023_tuned``).
        reference: the paper's compensator (``li2023``).

    Returns:
        ``(best, rows)``: the chosen label and, per candidate, its checks against the default
        (:data:`drillgym.eval.learning.seed_checks.CHECK_COLUMNS`, ``run`` = the candidate) plus
        ``mean_deviation_mm`` (averaged over suites).
    """
    frame = normalise_episodes(episodes)
    baselines = frame[frame["controller"] != POLICY].copy()
    known = set(baselines["controller"])
    missing = [c for c in [default, *candidates] if c not in known]
    if missing:
        raise UserError(f"no judge episodes of {missing}; baselines judged: {sorted(known)}")
    rows = []
    for candidate in candidates:
        if candidate == default:
            continue
        as_policy = baselines.copy()
        mask = as_policy["controller"] == candidate
        as_policy.loc[mask, "run"] = candidate
        as_policy.loc[mask, "controller"] = POLICY
        row = run_checks(as_policy, candidate, default, reference)
        row["mean_deviation_mm"] = _mean_over_suites(baselines, candidate)
        rows.append(row)
    passing = [r for r in rows if r["passes"]]
    if not passing:
        return default, rows
    best = min(passing, key=lambda r: r["mean_deviation_mm"])
    return str(best["run"]), rows


def _mean_over_suites(frame: pd.DataFrame, controller: str) -> float:
    rows = frame[frame["controller"] == controller]
    return float(np.mean([g[DEVIATION].mean() for _, g in rows.groupby("suite")]))


def describe(best: str, default: str, rows: list[dict[str, Any]]) -> list[str]:
    """Markdown lines: the rule, each candidate's checks, the choice."""
    lines = ["## The best classical baseline", "", f"Rule (fixed before judging): {RULE}.", ""]
    if not rows:
        return [*lines, f"No other classical candidate was judged: `{default}`.", ""]
    lines += ["| candidate vs `" + default + "` | " + " | ".join(RULES) + " | passes | mean deviation (mm) |"]
    lines += ["|---|" + "---|" * (len(RULES) + 2)]
    for r in rows:
        marks = " | ".join("✓" if r[k] else "✗" for k in (*RULES, "passes"))
        lines.append(f"| `{r['run']}` | {marks} | {r['mean_deviation_mm']:.4f} |")
    return [*lines, "", f"**Best classical baseline: `{best}`**", ""]


def against_each(episodes: pd.DataFrame, candidates: Sequence[str], suites: Sequence[str]) -> list[dict[str, Any]]:
    """Every policy run against every classical candidate: paired deviation difference per suite (pooled).

    Whatever the rule chose, a reader sees how each seed fares against each classical controller; rows hold
    ``run``, ``baseline``, and per suite ``{suite}_mean/low/high`` (mm, policy minus baseline, 95 % t CI).
    """
    frame = normalise_episodes(episodes)
    runs = sorted(set(frame.loc[frame["controller"] == POLICY, "run"]), key=_natural)
    rows = []
    for run in runs:
        for baseline in candidates:
            row: dict[str, Any] = {"run": run, "baseline": baseline}
            for suite in suites:
                d = paired_diff(frame, run, POLICY, baseline, suite, DEVIATION)
                row |= {f"{suite}_{k}": d[k] for k in ("mean", "low", "high")}
            rows.append(row)
    return rows


def describe_against_each(rows: list[dict[str, Any]], suites: Sequence[str]) -> list[str]:
    """Markdown table of :func:`against_each` (bold: the CI excludes 0)."""
    lines = ["## Each training seed against each classical baseline (Δ deviation, mm, pooled per suite)", ""]
    lines += ["| run | baseline | " + " | ".join(suites) + " |", "|---|---|" + "---|" * len(suites)]
    for r in rows:
        cells = []
        for s in suites:
            mean, low, high = r[f"{s}_mean"], r[f"{s}_low"], r[f"{s}_high"]
            text = f"{mean:+.4f} [{low:+.4f}, {high:+.4f}]"
            cells.append(f"**{text}**" if (high < 0.0 or low > 0.0) else text)
        lines.append(f"| {r['run']} | `{r['baseline']}` | " + " | ".join(cells) + " |")
    return [*lines, ""]
