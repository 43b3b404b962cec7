"""Benchmark statistics: means with 95% confidence intervals, paired differences, a Markdown report.

CI of the mean: Student t with n-1 degrees of freedom, ``mean ± t(0.975, n-1) · s / √n``; for n = 1
the interval is the value itself. Non-finite values (a metric undefined in an episode) are left out,
so ``n`` counts the episodes that define the metric. Paired differences compare a controller with
the baseline (the reference controller, by default the first) on the same seeds; a difference is
significant when its 95% CI excludes 0 (:func:`significant`, :func:`verdict`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import special

SUMMARY_COLUMNS = ("suite", "scenario", "controller", "metric", "mean", "ci_low", "ci_high", "n")
"""Columns of ``summary.csv`` (long form), in order."""
PAIRED_COLUMNS = ("suite", "scenario", "controller", "baseline", "metric", "mean", "ci_low", "ci_high", "n")
"""Columns of ``paired.csv``: controller minus baseline, paired by seed."""
CONFIDENCE = 0.95


def mean_ci(values: Sequence[float] | np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float, float, int]:
    """``(mean, ci_low, ci_high, n)`` of the finite values; NaNs and n = 0 if there are none.

    One value has a mean but no interval: its bounds are NaN, not a zero-width interval.
    """
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return math.nan, math.nan, math.nan, 0
    mean = float(x.mean())
    if n == 1:
        return mean, math.nan, math.nan, 1
    # special.stdtrit(df, q) is what scipy.stats.t.ppf(q, df) computes, without importing scipy.stats (~1 s)
    half = float(special.stdtrit(n - 1, 0.5 + confidence / 2.0)) * float(x.std(ddof=1)) / math.sqrt(n)
    return mean, mean - half, mean + half, n


def summarize(episodes: pd.DataFrame, metrics: Sequence[str], groups: Sequence[tuple[str, str, str]]) -> pd.DataFrame:
    """Long-form summary: one row per (suite, scenario, controller) in ``groups`` order × metric."""
    rows = []
    for suite, scenario, controller in groups:
        sel = episodes[
            (episodes["suite"] == suite) & (episodes["scenario"] == scenario) & (episodes["controller"] == controller)
        ]
        for metric in metrics:
            rows.append((suite, scenario, controller, metric, *mean_ci(sel[metric].to_numpy(dtype=float))))
    return pd.DataFrame(rows, columns=list(SUMMARY_COLUMNS))


def paired_differences(
    episodes: pd.DataFrame, metrics: Sequence[str], groups: Sequence[tuple[str, str, str]], baseline: str
) -> pd.DataFrame:
    """Controller minus ``baseline`` per seed, for every non-baseline group; mean and CI of the differences."""
    rows = []
    for suite, scenario, controller in groups:
        if controller == baseline:
            continue
        here = episodes[(episodes["suite"] == suite) & (episodes["scenario"] == scenario)]
        a = here[here["controller"] == controller].set_index("seed")
        b = here[here["controller"] == baseline].set_index("seed")
        seeds = a.index.intersection(b.index)
        for metric in metrics:
            diff = a.loc[seeds, metric].to_numpy(dtype=float) - b.loc[seeds, metric].to_numpy(dtype=float)
            rows.append((suite, scenario, controller, baseline, metric, *mean_ci(diff)))
    return pd.DataFrame(rows, columns=list(PAIRED_COLUMNS))


def significant(ci_low: float, ci_high: float) -> bool:
    """Whether a CI excludes 0 (False without an interval, e.g. from one pair)."""
    return math.isfinite(ci_low) and math.isfinite(ci_high) and (ci_low > 0.0 or ci_high < 0.0)


UNIT_SUFFIXES = {"_mm": "mm", "_n": "N", "_s": "s"}
"""Unit of a metric from its name's suffix (``deviation_mean_mm`` is in mm)."""


def metric_unit(metric: str) -> str:
    """``"mm"`` for ``"deviation_mean_mm"``, ``"N"`` for ``"lateral_force_max_n"``; ``""`` if the name has none."""
    return next((unit for suffix, unit in UNIT_SUFFIXES.items() if metric.endswith(suffix)), "")


def verdict(metric: str, controller: str, reference: str, mean: float, ci_low: float, ci_high: float, n: int) -> str:
    """One line on ``controller`` minus ``reference`` for a metric, from the paired difference's mean and 95% CI.

    ``"deviation_mean_mm: `b` lower than `a` (-0.107 [-0.115, -0.0988] mm, CI excludes 0)"``; "higher than" for
    a CI above 0, "no significant difference" for one that holds 0; no verdict without an interval (n < 2).
    The difference is in the metric's unit (:func:`metric_unit`).
    """
    unit = metric_unit(metric)
    delta = format_ci(mean, ci_low, ci_high) + (f" {unit}" if unit else "")
    if n == 0 or not math.isfinite(mean):
        return f"{metric}: `{controller}` vs `{reference}`: no paired episodes"
    if not (math.isfinite(ci_low) and math.isfinite(ci_high)):
        return f"{metric}: `{controller}` vs `{reference}`: {delta}, one pair, no CI (needs 2 or more seeds)"
    if significant(ci_low, ci_high):
        word = "lower" if mean < 0 else "higher"
        return f"{metric}: `{controller}` {word} than `{reference}` ({delta}, CI excludes 0)"
    return f"{metric}: no significant difference between `{controller}` and `{reference}` ({delta}, CI includes 0)"


def verdict_lines(paired: pd.DataFrame, metrics: Sequence[str], scenario: str) -> list[str]:
    """:func:`verdict` for every controller of ``paired`` (in its order) and metric, on one scenario of it."""
    here = paired[paired["scenario"] == scenario]
    cells = {(r["controller"], r["metric"]): r for r in here.to_dict("records")}
    lines = []
    for controller in dict.fromkeys(here["controller"]):
        for metric in metrics:
            r = cells.get((controller, metric))
            if r is not None:
                stats_ = (float(r["mean"]), float(r["ci_low"]), float(r["ci_high"]), int(r["n"]))
                lines.append(verdict(metric, str(controller), str(r["baseline"]), *stats_))
    return lines


def format_ci(mean: float, low: float, high: float) -> str:
    """``"0.712 [0.69, 0.734]"`` (3 significant digits), ``"0.712 [–]"`` without an interval, ``"-"`` if undefined."""
    if not math.isfinite(mean):
        return "-"
    if not (math.isfinite(low) and math.isfinite(high)):
        return f"{mean:.3g} [–]"
    return f"{mean:.3g} [{low:.3g}, {high:.3g}]"


def md_cell(value: object) -> str:
    """One Markdown table cell: ``|`` escaped, line breaks as spaces."""
    return " ".join(str(value).split()).replace("|", "\\|")


def md_table(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table with every cell escaped (:func:`md_cell`), so text in a cell never splits a row."""
    lines = ["| " + " | ".join(md_cell(h) for h in headers) + " |", "|" + "---|" * len(headers)]
    lines += ["| " + " | ".join(md_cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def markdown_table(long: pd.DataFrame, metrics: Sequence[str], label: str = "", bold_significant: bool = False) -> str:
    """Rows scenario × controller, one column per metric as ``mean [ci_low, ci_high]``, plus n.

    With ``bold_significant`` (paired differences), a cell whose CI excludes 0 is in bold: ``**-0.1 [-0.2, -0.05]**``.
    """
    head = ["scenario", "controller", "n", *(f"{label}{m}" for m in metrics)]
    rows = []
    keys = list(dict.fromkeys(zip(long["scenario"], long["controller"], strict=True)))
    cells = {
        (r["scenario"], r["controller"], r["metric"]): (
            float(r["mean"]),
            float(r["ci_low"]),
            float(r["ci_high"]),
            int(r["n"]),
        )
        for r in long.to_dict("records")
    }
    for scenario, controller in keys:
        stats_ = [cells.get((scenario, controller, m)) for m in metrics]
        n = max((s[3] for s in stats_ if s is not None), default=0)
        vals = [_cell(s, bold_significant) for s in stats_]
        rows.append([scenario, f"`{controller}`", n, *vals])
    return md_table(head, rows)


def _cell(stat: tuple[float, float, float, int] | None, bold_significant: bool) -> str:
    """``mean [ci_low, ci_high]`` of one table cell, in bold if asked and significant; ``"-"`` without a value."""
    if stat is None:
        return "-"
    text = format_ci(*stat[:3])
    return f"**{text}**" if bold_significant and significant(stat[1], stat[2]) else text
