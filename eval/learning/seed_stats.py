"""Across-seed statistics of a trained residual policy against deterministic baselines, in the style of rliable.

Agarwal et al. 2021, "Deep RL at the edge of the statistical precipice": a policy trained on several seeds is
summarised by the interquartile mean (IQM) of its per-run, per-task scores with a stratified-bootstrap confidence
interval, and by the probability of improvement over each baseline. Here a *run* is one training seed of the
policy (``"seed0"`` ...) and a *task* is one scenario of a suite; a run's score on a task is the mean of the metric
over the episode seeds. The baselines (``li2023``, ``li2023_tuned``, ...) are deterministic, not trained:
they have one run, labelled ``""``.

Lower is better for every metric used here (``deviation_mean_mm`` in mm, ``lateral_force_max_n`` in N,
``drill_time_s`` in s), so "improvement" means a *lower* value.

Paired episodes: the same ``(scenario, seed)`` episode is run by the policy and by the baseline, and the
per-episode differences give a Student-t interval (:func:`paired_diff`). Episodes whose metric is NaN (failed) are
dropped together with their partner, and the number dropped is reported.

The acceptance rules built on these figures are in :mod:`drillgym.eval.learning.seed_checks`; the report that
writes them in :mod:`drillgym.eval.learning.seed_report`.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from scipy import stats

POLICY = "policy"
"""``controller`` label of the trained policy's rows (its training run is in ``run``)."""
DEVIATION = "deviation_mean_mm"
FORCE = "lateral_force_max_n"
TIME = "drill_time_s"
METRICS = (DEVIATION, FORCE, TIME)
"""Metrics of the report; lower is better for each."""
UNITS = {DEVIATION: "mm", FORCE: "N", TIME: "s"}
KEY = ["scenario", "seed"]
"""An episode of one controller (and run) within a suite: the pairing key of the paired design."""
CONFIDENCE = 0.95


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
    frame["run"] = frame["run"].astype(object).fillna("").astype(str)  # a float column of NaN (baselines only)
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
