"""The seed report: a trained residual policy's seeds judged against deterministic baselines, written down.

The figures (in the style of rliable: IQM of per-run, per-task scores with stratified-bootstrap intervals, the
probability of improvement, paired differences; lower is better) are :mod:`drillgym.eval.learning.seed_stats`'s.

Next to the aggregate figures, every training seed is checked alone
(:func:`drillgym.eval.learning.seed_checks.seed_checks`) on paired episodes. The statistics are in
:mod:`drillgym.eval.learning.seed_stats`, the acceptance rules in :mod:`drillgym.eval.learning.seed_checks`; this
module writes them down.

:func:`write_seed_report` writes ``seed_report.json`` (every figure), ``seed_report.md`` and ``seed_report.png``.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from drillgym.envs.json_safe import json_safe
from drillgym.eval.learning.seed_checks import HELDOUT, PAPER, RULES, seed_checks
from drillgym.eval.learning.seed_stats import (
    CONFIDENCE,
    DEVIATION,
    METRICS,
    POLICY,
    UNITS,
    _natural,
    _score_matrix,
    iqm,
    normalise_episodes,
    probability_of_improvement_ci,
    stratified_bootstrap_ci,
)

# --------------------------------------------------------------------------------------------- report


def _ordered_suites(frame: pd.DataFrame) -> list[str]:
    present = set(frame["suite"])
    return [s for s in (PAPER, HELDOUT) if s in present] + sorted(present - {PAPER, HELDOUT})


def _aggregate(frame: pd.DataFrame, suite: str, metric: str, controllers: Sequence[str], reps: int) -> dict[str, Any]:
    """IQM [CI] of each controller on the tasks where every controller with episodes has a finite score."""
    matrices = {c: _score_matrix(frame, c, suite, metric) for c in controllers}
    matrices = {c: m for c, m in matrices.items() if m[0].shape[0] > 0}
    tasks = next(iter(matrices.values()))[2] if matrices else []
    valid = np.ones(len(tasks), dtype=bool)
    for scores, _, _ in matrices.values():
        valid &= np.all(np.isfinite(scores), axis=0)
    entry: dict[str, Any] = {
        "tasks": [t for t, v in zip(tasks, valid, strict=True) if v],
        "dropped_tasks": [t for t, v in zip(tasks, valid, strict=True) if not v],
        "by_controller": {},
    }
    if not valid.any():
        return entry
    for c, (scores, runs, _) in matrices.items():
        point, low, high = stratified_bootstrap_ci(scores[:, valid], iqm, reps=reps)
        entry["by_controller"][c] = {"iqm": point, "low": low, "high": high, "runs": runs}
    return entry


def _improvement(frame: pd.DataFrame, suite: str, baseline: str, reps: int) -> dict[str, Any] | None:
    x, runs, tasks = _score_matrix(frame, POLICY, suite, DEVIATION)
    y, base_runs, _ = _score_matrix(frame, baseline, suite, DEVIATION)
    if x.shape[0] == 0 or y.shape[0] == 0:
        return None
    valid = np.all(np.isfinite(x), axis=0) & np.all(np.isfinite(y), axis=0)
    if not valid.any():
        return None
    p, low, high = probability_of_improvement_ci(x[:, valid], y[:, valid], reps=reps)
    used = [t for t, v in zip(tasks, valid, strict=True) if v]
    return {"p": p, "low": low, "high": high, "policy_runs": len(runs), "baseline_runs": len(base_runs), "tasks": used}


def _failed(frame: pd.DataFrame) -> dict[str, dict[str, int]]:
    bad = frame[frame[list(METRICS)].isna().any(axis=1)]
    counts: dict[str, dict[str, int]] = {}
    sizes = bad.groupby(["suite", "controller", "run"], as_index=False).size()
    for suite, controller, run, n in zip(sizes["suite"], sizes["controller"], sizes["run"], sizes["size"], strict=True):
        counts.setdefault(str(suite), {})[f"{controller} {run}".strip()] = int(n)
    return counts


def write_seed_report(
    episodes: pd.DataFrame,
    out: Path,
    best_baseline: str,
    reference: str = "li2023",
    reps: int = 2000,
    extra: dict[str, Any] | None = None,
    extra_markdown: Sequence[str] = (),
) -> dict[str, Any]:
    """Write ``seed_report.json``, ``seed_report.md`` and ``seed_report.png`` into ``out``.

    The JSON holds: ``per_seed`` (the :func:`seed_checks` rows), ``aggregate[suite][metric]`` (IQM over runs x
    tasks with a 95 % stratified-bootstrap CI, ``reps`` samples, for the policy across its runs and for each
    baseline's single run; tasks with a NaN score for any controller are left out and listed in
    ``dropped_tasks``), ``probability_of_improvement[suite][baseline]`` (P(policy < baseline) on
    ``deviation_mean_mm`` with its CI), ``failed_episodes`` and ``passing_runs`` of ``n_runs``.

    Args:
        episodes: one row per episode (see :func:`score_matrix`); policy rows have ``controller == "policy"``.
        out: output folder (created if missing).
        best_baseline: the strongest baseline's label.
        reference: the paper's compensator's label.
        reps: bootstrap samples of every interval.
        extra: more entries for the JSON (e.g. how the best baseline and the shipped seed were chosen).
        extra_markdown: lines appended to ``seed_report.md`` after the per-seed tables' summary line.

    Returns:
        The dict written to ``seed_report.json`` (NaN written as null).
    """
    frame = normalise_episodes(episodes)
    out.mkdir(parents=True, exist_ok=True)
    checks = seed_checks(frame, best_baseline, reference)
    suites = _ordered_suites(frame)
    baselines = sorted(set(frame["controller"]) - {POLICY}, key=_natural)
    controllers = [POLICY, *baselines]
    passing = [str(r) for r in checks.loc[checks["passes"].astype(bool), "run"]]
    report: dict[str, Any] = {
        "best_baseline": best_baseline,
        "reference": reference,
        "policy": POLICY,
        "baselines": baselines,
        "suites": suites,
        "metrics": {m: UNITS[m] for m in METRICS},
        "lower_is_better": True,
        "statistic": "IQM = scipy.stats.trim_mean(scores over runs x tasks, 0.25); task score = mean over episodes",
        "interval": f"stratified bootstrap (runs resampled within each task), percentile, {reps} samples",
        "confidence": CONFIDENCE,
        "rules": RULES,
        "per_seed": checks.to_dict(orient="records"),
        "aggregate": {s: {m: _aggregate(frame, s, m, controllers, reps) for m in METRICS} for s in suites},
        "probability_of_improvement": {s: {b: _improvement(frame, s, b, reps) for b in baselines} for s in suites},
        "failed_episodes": _failed(frame),
        "runs": [str(r) for r in checks["run"]],
        "passing": passing,
        "passing_runs": len(passing),
        "n_runs": len(checks),
        **(extra or {}),
    }
    report = json_safe(report)
    (out / "seed_report.json").write_text(json.dumps(report, indent=2, allow_nan=False) + "\n")
    (out / "seed_report.md").write_text(_markdown(report, extra_markdown))
    _plot(report, out / "seed_report.png")
    return report


# --------------------------------------------------------------------------------------------- markdown


def _num(x: float | None, digits: int = 2) -> str:
    return "n/a" if x is None else f"{x:.{digits}f}"


def _ci(mean: float | None, low: float | None, high: float | None, digits: int = 2) -> str:
    if mean is None:
        return "n/a"
    return f"{_num(mean, digits)} [{_num(low, digits)}, {_num(high, digits)}]"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(r) + " |" for r in rows]


def _seed_tables(report: dict[str, Any]) -> list[str]:
    best, ref = report["best_baseline"], report["reference"]
    header = [
        "run",
        f"paper Δdeviation vs {best} (mm)",
        f"paper Δpeak force vs {best} (N)",
        f"paper deviation vs {ref} (%)",
        f"generalisation Δdeviation vs {best} (mm)",
        f"heldout Δdeviation vs {best} (mm)",
        "heldout scenarios worse",
        f"paper drill time vs {best} (%)",
    ]
    rows = []
    for r in report["per_seed"]:
        d = [_ci(r[f"{p}_mean"], r[f"{p}_low"], r[f"{p}_high"], 3) for p in ("paper_deviation", "paper_force")]
        general = _ci(
            r["generalisation_deviation_mean"], r["generalisation_deviation_low"], r["generalisation_deviation_high"], 3
        )
        held = _ci(r["heldout_deviation_mean"], r["heldout_deviation_low"], r["heldout_deviation_high"], 3)
        worse = ", ".join(r["heldout_worse_scenarios"]) or ("none" if r["heldout_deviation_n"] else "n/a")
        rel = _num(r["paper_deviation_vs_reference_pct"], 1)
        rows.append([r["run"], *d, rel, general, held, worse, _num(r["paper_time_vs_best_pct"], 1)])
    lines = ["## Per training seed", "", *_table(header, rows), ""]
    checks = [[r["run"], *("✓" if r[k] else "✗" for k in (*RULES, "passes")), r["notes"]] for r in report["per_seed"]]
    lines += _table(["run", *RULES, "passes", "notes"], checks)
    lines += ["", *(f"- `{k}`: {v}" for k, v in RULES.items()), ""]
    return lines


def _aggregate_tables(report: dict[str, Any]) -> list[str]:
    suites = report["suites"]
    lines = ["## Aggregate: IQM [95 % CI] over training seeds x scenarios", ""]
    for metric, unit in report["metrics"].items():
        rows = []
        for c in [report["policy"], *report["baselines"]]:
            cells = []
            for s in suites:
                e = report["aggregate"][s][metric]["by_controller"].get(c)
                cells.append("n/a" if e is None else _ci(e["iqm"], e["low"], e["high"], 3))
            rows.append([c, *cells])
        lines += [f"### {metric} ({unit})", "", *_table(["controller", *suites], rows), ""]
        dropped = {s: report["aggregate"][s][metric]["dropped_tasks"] for s in suites}
        lines += [f"Scenarios left out (a NaN score): {s}: {', '.join(t)}" for s, t in dropped.items() if t]
    return lines


def _improvement_table(report: dict[str, Any]) -> list[str]:
    suites = report["suites"]
    rows = []
    for b in report["baselines"]:
        cells = []
        for s in suites:
            e = report["probability_of_improvement"][s][b]
            cells.append("n/a" if e is None else _ci(e["p"], e["low"], e["high"]))
        rows.append([b, *cells])
    return [
        "## Probability of improvement P(policy < baseline) on deviation_mean_mm [95 % CI]",
        "",
        "Per scenario, the share of (training seed, baseline run) pairs where the policy's mean deviation is",
        "lower (ties count half), averaged over scenarios. For a deterministic baseline (one run) this is the",
        "fraction of training seeds that beat it; 0.5 means no improvement.",
        "",
        *_table(["baseline", *suites], rows),
        "",
    ]


def _markdown(report: dict[str, Any], extra: Sequence[str] = ()) -> str:
    lines = [
        "# Training seeds against the baselines",
        "",
        f"Policy `{report['policy']}` over {report['n_runs']} training seeds; best baseline `{report['best_baseline']}`,"
        f" reference `{report['reference']}`. Lower is better for every metric. Paired differences are policy minus",
        "baseline on the same (scenario, episode seed), Student-t 95 % CI.",
        "",
        f"**{report['passing_runs']} of {report['n_runs']} training seeds pass every check**",
        "",
        *extra,
    ]
    lines += _seed_tables(report) + _aggregate_tables(report) + _improvement_table(report)
    failed = report["failed_episodes"]
    if failed:
        lines.append("Failed episodes (NaN metric, left out): ")
        lines += [f"- {s}: " + ", ".join(f"{c}: {n}" for c, n in by.items()) for s, by in failed.items()]
    lines += ["", report["statistic"] + "; " + report["interval"] + ".", ""]
    return "\n".join(lines)


# --------------------------------------------------------------------------------------------- figure


def _errorbar(ax: Any, x: float, entry: dict[str, Any] | None, keys: tuple[str, str, str], **style: Any) -> None:
    if entry is None or entry[keys[0]] is None:
        return
    y, low, high = (entry[k] for k in keys)
    yerr = np.nan_to_num(np.array([[y - low], [high - y]]))
    ax.errorbar([x], [y], yerr=yerr, capsize=4, **style)


def _plot(report: dict[str, Any], path: Path) -> None:
    suites = report["suites"]
    baselines = report["baselines"]
    fig = Figure(figsize=(10.0, 4.0), layout="constrained")
    FigureCanvasAgg(fig)
    left, right = fig.subplots(1, 2)
    width = 0.5 / max(len(baselines) + 1, 1)
    left_offset = -width * len(baselines) / 2  # policy then the baselines, centred on the suite's tick
    right_offset = -width * (len(baselines) - 1) / 2
    markers = "sD^v<>ph"
    for i, s in enumerate(suites):
        by = report["aggregate"][s][DEVIATION]["by_controller"]
        _errorbar(
            left,
            i + left_offset,
            by.get(POLICY),
            ("iqm", "low", "high"),
            fmt="o",
            color="C0",
            label=POLICY if i == 0 else None,
        )
        for j, b in enumerate(baselines):
            style = {"fmt": markers[j % len(markers)], "color": f"C{j + 1}", "label": b if i == 0 else None}
            _errorbar(left, i + left_offset + (j + 1) * width, by.get(b), ("iqm", "low", "high"), **style)
            poi = report["probability_of_improvement"][s][b]
            _errorbar(right, i + right_offset + j * width, poi, ("p", "low", "high"), **style)
    for ax in (left, right):
        ax.set_xticks(np.arange(len(suites)), suites)
        ax.set_xlim(-0.5, len(suites) - 0.5)
        ax.grid(axis="y", alpha=0.3)
    left.set_ylabel("IQM mean tip deviation (mm), lower is better")
    left.set_title("IQM deviation [95 % CI]")
    right.axhline(0.5, color="grey", linestyle="--", linewidth=1)
    right.set_ylim(-0.02, 1.02)
    right.set_ylabel("P(policy < baseline)")
    right.set_title("probability of improvement [95 % CI]")
    if suites:
        left.legend(fontsize="small")
        right.legend(fontsize="small")
    fig.savefig(path, dpi=120)
