"""Benchmark statistics: means with 95% confidence intervals, paired differences, a Markdown report.

CI of the mean: Student t with n-1 degrees of freedom, ``mean ± t(0.975, n-1) · s / √n``; for n = 1
the interval is the value itself. Non-finite values (a metric undefined in an episode) are left out,
so ``n`` counts the episodes that define the metric. Paired differences compare a controller with
the baseline (the first controller) on the same seeds.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pandas as pd
from scipy import stats

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
    half = float(stats.t.ppf(0.5 + confidence / 2.0, n - 1)) * float(x.std(ddof=1)) / math.sqrt(n)
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


def markdown_table(long: pd.DataFrame, metrics: Sequence[str], label: str = "") -> str:
    """Rows scenario × controller, one column per metric as ``mean [ci_low, ci_high]``, plus n."""
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
        vals = [format_ci(*s[:3]) if s is not None else "-" for s in stats_]
        rows.append([scenario, f"`{controller}`", n, *vals])
    return md_table(head, rows)
