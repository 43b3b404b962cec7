"""Across-seed judgement of a trained residual policy against deterministic baselines, in the style of rliable.

Agarwal et al. 2021, "Deep RL at the edge of the statistical precipice": a policy trained on several seeds is
summarised by the interquartile mean (IQM) of its per-run, per-task scores with a stratified-bootstrap confidence
interval, and by the probability of improvement over each baseline. Here a *run* is one training seed of the
policy (``"seed0"`` ...) and a *task* is one scenario of a suite; a run's score on a task is the mean of the metric
over the episode seeds. The baselines (``li2023``, ``li2023_tuned``, ...) are deterministic, not trained:
they have one run, labelled ``""``.

Lower is better for every metric used here (``deviation_mean_mm`` in mm, ``lateral_force_max_n`` in N,
``drill_time_s`` in s), so "improvement" means a *lower* value.

Next to the aggregate figures, every training seed is checked alone (:func:`seed_checks`) on paired episodes:
the same ``(scenario, seed)`` episode is run by the policy and by the baseline, and the per-episode differences
give a Student-t interval (:func:`paired_diff`). Episodes whose metric is NaN (failed) are dropped together with
their partner, and the number dropped is reported.

:func:`write_seed_report` writes ``seed_report.json`` (every figure), ``seed_report.md`` and ``seed_report.png``.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from scipy import stats

from drillgym.envs.json_safe import json_safe

POLICY = "policy"
"""``controller`` label of the trained policy's rows (its training run is in ``run``)."""
DEVIATION = "deviation_mean_mm"
FORCE = "lateral_force_max_n"
TIME = "drill_time_s"
METRICS = (DEVIATION, FORCE, TIME)
"""Metrics of the report; lower is better for each."""
UNITS = {DEVIATION: "mm", FORCE: "N", TIME: "s"}
PAPER = "paper"
HELDOUT = "heldout"
GENERALISATION = "generalisation"
KEY = ["scenario", "seed"]
"""An episode of one controller (and run) within a suite: the pairing key of the paired design."""
CONFIDENCE = 0.95
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


# --------------------------------------------------------------------------------------------- statistics


def iqm(x: np.ndarray) -> float:
    """Interquartile mean: the mean of the middle 50 % of the values.

    Computed as ``scipy.stats.trim_mean(x, 0.25)`` on the flattened values (what rliable's ``aggregate_iqm``
    does): ``int(0.25 * n)`` values are cut from each end, so for sizes not divisible by 4 slightly more than
    half of the values remain.

    Args:
        x: values of any shape, in the metric's unit; must not be empty.

    Returns:
        The interquartile mean, in the metric's unit.

    Raises:
        ValueError: if ``x`` is empty.
    """
    values = np.asarray(x, dtype=float).ravel()
    if values.size == 0:
        raise ValueError("iqm of an empty array")
    return float(stats.trim_mean(values, 0.25))


def _matrix(scores: np.ndarray, name: str) -> np.ndarray:
    m = np.asarray(scores, dtype=float)
    if m.ndim != 2 or m.shape[0] == 0 or m.shape[1] == 0:
        raise ValueError(f"{name} must be a non-empty [runs, tasks] matrix, got shape {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError(f"{name} holds NaN or infinite scores: drop those tasks first")
    return m


def _percentiles(boot: np.ndarray, confidence: float) -> tuple[float, float]:
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = np.percentile(boot, [tail, 100.0 - tail])
    return float(low), float(high)


def stratified_bootstrap_ci(
    scores: np.ndarray,
    statistic: Callable[[np.ndarray], float] = iqm,
    reps: int = 2000,
    confidence: float = CONFIDENCE,
    rng_seed: int = 0,
) -> tuple[float, float, float]:
    """Point estimate and percentile interval of an aggregate statistic by rliable's stratified bootstrap.

    Each bootstrap sample draws, independently within each task (column), as many runs as there are with
    replacement; ``statistic`` is applied to the flattened resampled matrix. A matrix with one run (a
    deterministic baseline) gives a degenerate interval equal to the point estimate.

    Args:
        scores: ``[runs, tasks]`` matrix of per-run, per-task scores (metric unit), all finite.
        statistic: aggregate of a 1-D array, e.g. :func:`iqm` or ``np.mean``.
        reps: number of bootstrap samples.
        confidence: coverage of the percentile interval, e.g. 0.95.
        rng_seed: seed of the NumPy generator (the result is deterministic).

    Returns:
        ``(point, low, high)`` in the metric's unit.

    Raises:
        ValueError: on an empty or non-finite matrix, ``reps < 1`` or a confidence outside (0, 1).
    """
    m = _matrix(scores, "scores")
    if reps < 1:
        raise ValueError(f"reps must be >= 1, got {reps}")
    point = float(statistic(m.ravel()))
    rng = np.random.default_rng(rng_seed)
    n_runs, n_tasks = m.shape
    columns = np.arange(n_tasks)
    boot = np.empty(reps)
    for b in range(reps):
        rows = rng.integers(0, n_runs, size=(n_runs, n_tasks))
        boot[b] = statistic(m[rows, columns].ravel())
    low, high = _percentiles(boot, confidence)
    return point, low, high


def _poi(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """P(X < Y) of ``x[..., runs_x, tasks]`` over ``y[..., runs_y, tasks]``, averaged over tasks."""
    xe = x[..., :, None, :]
    ye = y[..., None, :, :]
    s = (xe < ye).astype(float) + 0.5 * (xe == ye)
    return np.asarray(s.mean(axis=(-3, -2)).mean(axis=-1))


def _pair(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mx, my = _matrix(x, "x"), _matrix(y, "y")
    if mx.shape[1] != my.shape[1]:
        raise ValueError(f"x and y must have the same tasks (columns), got {mx.shape[1]} and {my.shape[1]}")
    return mx, my


def probability_of_improvement(x: np.ndarray, y: np.ndarray) -> float:
    """Probability that X improves on Y, i.e. P(X < Y) since lower is better (rliable's definition).

    For each task the Mann-Whitney statistic ``mean_ij S(x_i, y_j)`` with ``S = 1`` if ``x_i < y_j``, ``0.5`` if
    equal and ``0`` otherwise; then the average over tasks. When ``y`` is a deterministic baseline (one run) this
    is, per task, the fraction of ``x``'s runs (training seeds) that beat it (ties half), averaged over tasks.

    Args:
        x: ``[runs_x, tasks]`` scores of the candidate (e.g. the policy's training seeds), all finite.
        y: ``[runs_y, tasks]`` scores of the comparison (e.g. a baseline, one run), same tasks, all finite.

    Returns:
        The probability of improvement in [0, 1]; 0.5 means neither is better.
    """
    mx, my = _pair(x, y)
    return float(_poi(mx, my))


def probability_of_improvement_ci(
    x: np.ndarray, y: np.ndarray, reps: int = 2000, confidence: float = CONFIDENCE, rng_seed: int = 0
) -> tuple[float, float, float]:
    """Probability of improvement P(X < Y) with a stratified-bootstrap percentile interval.

    Each bootstrap sample resamples, independently within each task, ``x``'s runs and ``y``'s runs with
    replacement (rliable's stratified bootstrap of both score matrices). A one-run ``y`` (deterministic
    baseline) is left as it is, so the interval then reflects only the spread over ``x``'s training seeds.

    Args:
        x: ``[runs_x, tasks]`` scores of the candidate, all finite.
        y: ``[runs_y, tasks]`` scores of the comparison, same tasks, all finite.
        reps: number of bootstrap samples.
        confidence: coverage of the percentile interval, e.g. 0.95.
        rng_seed: seed of the NumPy generator.

    Returns:
        ``(point, low, high)``, probabilities in [0, 1].
    """
    mx, my = _pair(x, y)
    if reps < 1:
        raise ValueError(f"reps must be >= 1, got {reps}")
    rng = np.random.default_rng(rng_seed)
    columns = np.arange(mx.shape[1])
    boot = np.empty(reps)
    chunk = 256
    for start in range(0, reps, chunk):
        k = min(chunk, reps - start)
        ix = rng.integers(0, mx.shape[0], size=(k, *mx.shape))
        iy = rng.integers(0, my.shape[0], size=(k, *my.shape))
        boot[start : start + k] = _poi(mx[ix, columns], my[iy, columns])
    low, high = _percentiles(boot, confidence)
    return float(_poi(mx, my)), low, high


# --------------------------------------------------------------------------------------------- episodes


def _natural(text: str) -> list[Any]:
    """Sort key: "seed2" before "seed10"."""
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", text)]


def normalise_episodes(episodes: pd.DataFrame) -> pd.DataFrame:
    """A copy with ``run`` as str ("" for NaN, as after a CSV round trip) and float metric columns."""
    required = {"run", "controller", "suite", "scenario", "seed"}
    missing = required - set(episodes.columns)
    if missing:
        raise ValueError(f"episodes lack the columns {sorted(missing)}")
    frame = episodes.copy()
    frame["run"] = frame["run"].fillna("").astype(str)
    for c in ("controller", "suite", "scenario"):
        frame[c] = frame[c].astype(str)
    frame["seed"] = frame["seed"].astype(int)
    for metric in METRICS:
        if metric in frame:
            frame[metric] = pd.to_numeric(frame[metric], errors="coerce").astype(float)
        else:
            frame[metric] = np.nan
    return frame


def score_matrix(
    episodes: pd.DataFrame, controller: str, suite: str, metric: str
) -> tuple[np.ndarray, list[str], list[str]]:
    """Per run and scenario of a suite, the mean of a metric over the episode seeds.

    Failed episodes (NaN metric) are left out of the mean; a cell is NaN if every episode of it failed or the
    controller has no episode of that scenario. The tasks are every scenario of the suite in ``episodes`` (any
    controller), sorted by name, so matrices of different controllers share their columns.

    Args:
        episodes: one row per episode (columns ``run``, ``controller``, ``suite``, ``scenario``, ``seed``, metric).
        controller: ``"policy"`` or a baseline label; a baseline has one run, ``""``.
        suite: e.g. ``"paper"`` or ``"heldout"``.
        metric: metric column, e.g. ``"deviation_mean_mm"`` (its unit is the scores' unit).

    Returns:
        ``(scores[runs, tasks], runs, tasks)``; runs in natural order ("seed2" before "seed10"), no rows if the
        controller has no episode in the suite.
    """
    frame = normalise_episodes(episodes)
    return _score_matrix(frame, controller, suite, metric)


def _score_matrix(
    frame: pd.DataFrame, controller: str, suite: str, metric: str
) -> tuple[np.ndarray, list[str], list[str]]:
    in_suite = frame[frame["suite"] == suite]
    tasks = sorted(set(in_suite["scenario"]))
    rows = in_suite[in_suite["controller"] == controller]
    runs = sorted(set(rows["run"]), key=_natural)
    scores = np.full((len(runs), len(tasks)), np.nan)
    means = rows.groupby(["run", "scenario"], as_index=False)[metric].mean()
    for run, scenario, value in zip(means["run"], means["scenario"], means[metric], strict=True):
        scores[runs.index(str(run)), tasks.index(str(scenario))] = value
    return scores, runs, tasks


def paired_diff(
    episodes: pd.DataFrame,
    run: str,
    policy: str,
    baseline: str,
    suite: str,
    metric: str,
    scenario: str | None = None,
    confidence: float = CONFIDENCE,
) -> dict[str, float]:
    """Policy minus baseline on the same ``(scenario, seed)`` episodes, with a Student-t interval.

    Args:
        episodes: one row per episode.
        run: the policy's training run, e.g. ``"seed0"``.
        policy: the policy's ``controller`` label, normally ``"policy"``.
        baseline: the baseline's ``controller`` label (one run); its episodes of any run are used.
        suite: the suite, e.g. ``"paper"``.
        metric: metric column; the differences are in its unit (mm, N, s).
        scenario: one scenario, or None to pool every scenario of the suite.
        confidence: coverage of the t interval (``scipy.stats.t``), 0.95 by default.

    Returns:
        ``mean``, ``low``, ``high`` of the per-episode difference (negative: the policy is lower, i.e. better);
        ``n`` pairs used; ``dropped``: pairs left out because either side is NaN (failed) or missing;
        ``policy_mean`` and ``baseline_mean``: the two sides' means over the pairs used. With no pair every
        figure is NaN; with one pair the interval is NaN.

    Raises:
        ValueError: if a side has two episodes with the same ``(scenario, seed)``.
    """
    return _paired(normalise_episodes(episodes), run, policy, baseline, suite, metric, scenario, confidence)


def _paired(
    frame: pd.DataFrame,
    run: str,
    policy: str,
    baseline: str,
    suite: str,
    metric: str,
    scenario: str | None = None,
    confidence: float = CONFIDENCE,
) -> dict[str, float]:
    sel = frame[frame["suite"] == suite]
    if scenario is not None:
        sel = sel[sel["scenario"] == scenario]
    cols = [*KEY, metric]
    pol = sel[(sel["controller"] == policy) & (sel["run"] == run)][cols]
    base = sel[sel["controller"] == baseline][cols]
    for label, part in ((f"{policy} {run}", pol), (baseline, base)):
        if part.duplicated(KEY).any():
            raise ValueError(f"{label} has several episodes with the same (scenario, seed) in suite {suite}")
    pairs = pol.merge(base, on=KEY, how="outer", suffixes=("_policy", "_baseline"))
    a = pairs[f"{metric}_policy"].to_numpy(dtype=float)
    b = pairs[f"{metric}_baseline"].to_numpy(dtype=float)
    ok = np.isfinite(a) & np.isfinite(b)
    d = a[ok] - b[ok]
    n = int(d.size)
    result = {"mean": math.nan, "low": math.nan, "high": math.nan, "n": n, "dropped": int((~ok).sum())}
    result |= {"policy_mean": math.nan, "baseline_mean": math.nan}
    if n == 0:
        return result
    result |= {"mean": float(d.mean()), "policy_mean": float(a[ok].mean()), "baseline_mean": float(b[ok].mean())}
    if n >= 2:
        half = float(stats.t.ppf((1.0 + confidence) / 2.0, n - 1) * d.std(ddof=1) / math.sqrt(n))
        result |= {"low": result["mean"] - half, "high": result["mean"] + half}
    return result


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
