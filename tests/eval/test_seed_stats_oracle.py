"""The across-seed statistics (:mod:`drillgym.eval.learning.seed_stats`) on tiny data worked out by hand.

Every expected value is computed in a comment (or by NumPy on the listed values), never with the module's
helpers. Bootstraps are checked on one-task, two-run matrices whose resampling distribution is known exactly:
two runs {0, 1} resampled with replacement have mean 0 with probability 1/4, 1/2 with 1/2 and 1 with 1/4, so a
percentile below 25 % is 0, between 25 % and 75 % is 1/2, above 75 % is 1. With 10,000 samples the share of
each outcome is within 4 · sqrt(0.25 · 0.75 / 10,000) = 0.017 of its probability (4 SD), so percentiles at
least 2.5 points away from 25 % and 75 % land in the stated block whatever the seed (the generator is seeded,
so the tests are deterministic anyway; the margin says they do not depend on the seed).
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.learning.seed_stats import (
    iqm,
    normalise_episodes,
    paired_diff,
    probability_of_improvement,
    probability_of_improvement_ci,
    score_matrix,
    stratified_bootstrap_ci,
)

T975_DF2 = 4.302652729749462  # Student t 97.5 % quantile, 2 degrees of freedom (tables: 4.303)
T95_DF2 = 2.919985580353724  # 95 % quantile, 2 degrees of freedom (tables: 2.920)
REPS = 10_000


# --------------------------------------------------------------------------------------------- IQM


@pytest.mark.parametrize(
    ("values", "expected"),
    [
        ([9.0, 1.0, 5.0, 3.0, 7.0, 100.0, -50.0, 2.0, 4.0, 6.0], (2 + 3 + 4 + 5 + 6 + 7) / 6),  # 10: 2 cut each end
        ([5.0, -1.0, 2.0, 3.0, 40.0], (2 + 3 + 5) / 3),  # 5: int(1.25) = 1 cut each end
        ([3.0, 1.0, 2.0], 2.0),  # 3: int(0.75) = 0 cut, the plain mean
        ([7.0], 7.0),
    ],
)
def test_iqm_cuts_a_quarter_of_the_values_rounded_down_from_each_end(values, expected):
    assert iqm(np.array(values)) == pytest.approx(expected, rel=1e-12)


def test_iqm_and_the_bootstrap_average_float32_scores_in_float64():
    """Scores read as float32 are averaged as float64 numbers. 2²⁴, 1, 1 are exact in float32, but a float32 sum in
    this order loses the 1s (2²⁴ + 1 rounds to 2²⁴): the mean is (2²⁴ + 2) / 3 = 5592406 exactly only in float64
    (float32 gives 5592405.5). For the IQM (which sorts first) 0.1, 0.2, 0.3 as float32: their float64 mean
    differs from the float32 one by 1.2e-8 relative; compared at 1e-12 relative (float64 rounding)."""
    values = np.array([2.0**24, 1.0, 1.0], dtype=np.float32)
    assert stratified_bootstrap_ci(values[:, None], np.mean, reps=1)[0] == 5592406.0
    tenths = np.array([0.1, 0.2, 0.3], dtype=np.float32)
    assert iqm(tenths) == pytest.approx(sum(float(v) for v in tenths) / 3.0, rel=1e-12, abs=0.0)


def test_iqm_flattens_a_matrix_and_refuses_an_empty_one():
    assert iqm(np.array([[1.0, 100.0], [2.0, 3.0]])) == pytest.approx(2.5, rel=1e-12)  # 4: drops 1 and 100
    assert iqm([[1, 2], [3, 4]]) == 2.5 and isinstance(iqm([1, 2]), float)  # any array-like of numbers
    with pytest.raises(ValueError, match=r"^iqm of an empty array$"):
        iqm(np.zeros((2, 0)))


# --------------------------------------------------------------------------------------------- bootstrap


def test_a_two_run_bootstrap_has_the_exact_percentiles_of_its_three_outcomes():
    """Runs {0, 1}, one task, statistic the mean: 95 % → (0, 1); 45 % → tails at 27.5 %: (1/2, 1/2); 60 % →
    tails at 20 %: (0, 1). The point estimate is the mean of the matrix, 1/2."""
    scores = np.array([[0.0], [1.0]])
    assert stratified_bootstrap_ci(scores, np.mean, reps=REPS) == (0.5, 0.0, 1.0)
    assert stratified_bootstrap_ci(scores, np.mean, reps=REPS, confidence=0.45) == (0.5, 0.5, 0.5)
    assert stratified_bootstrap_ci(scores, np.mean, reps=REPS, confidence=0.6) == (0.5, 0.0, 1.0)


def test_the_interval_is_numpys_linear_percentile_of_the_bootstrap_samples():
    """A statistic that counts its calls makes the 101 bootstrap samples an arithmetic run a, a + 1, ..., a + 100
    (a = 1 if the point estimate is taken first, else 0), whose p-th linear percentile is a + p: 95 % gives
    (a + 2.5, a + 97.5), 80 % (a + 10, a + 90)."""
    for confidence, (low_p, high_p) in ((0.95, (2.5, 97.5)), (0.8, (10.0, 90.0))):
        calls = iter(range(1000))
        count = functools.partial(lambda it, v: float(next(it)), calls)
        point, low, high = stratified_bootstrap_ci(np.ones((2, 1)), count, 101, confidence)
        a = 1.0 if point == 0.0 else 0.0
        assert (low, high) == pytest.approx((a + low_p, a + high_p), abs=1e-9)


def test_both_bootstraps_draw_2000_samples_by_default():
    """The report's documented 2000 samples: the statistic is called 2000 times besides the point estimate, and
    the improvement interval's default equals its explicit 2000-sample result."""
    calls = []
    stratified_bootstrap_ci(np.ones((2, 1)), lambda v: float(calls.append(1) or 0.0))
    assert len(calls) == 2001
    rng = np.random.default_rng(4)
    x, y = rng.normal(size=(5, 3)), rng.normal(size=(4, 3))
    assert probability_of_improvement_ci(x, y) == probability_of_improvement_ci(x, y, reps=2000)


def test_the_bootstrap_statistic_sees_the_whole_resampled_matrix_flattened():
    """A statistic returning its argument's size: 3 runs x 2 tasks resampled are 6 values, every time."""
    sizes = []

    def size(v: np.ndarray) -> float:
        sizes.append(v.shape)
        return float(v.size)

    assert stratified_bootstrap_ci(np.ones((3, 2)), size, reps=7) == (6.0, 6.0, 6.0)
    assert sizes == [(6,)] * 8  # the point estimate and the 7 samples, each 1-D


def test_the_bootstrap_resamples_runs_within_each_task_with_replacement():
    """Task 0 has runs {0, 1}, task 1 {10, 10}: the mean over the 4 resampled values is 5 + (task 0's mean) / 2,
    so 5, 5.25 or 5.5 with probabilities 1/4, 1/2, 1/4: a 95 % interval (5, 5.5); 45 % gives (5.25, 5.25)."""
    scores = np.array([[0.0, 10.0], [1.0, 10.0]])
    assert stratified_bootstrap_ci(scores, np.mean, reps=REPS) == (5.25, 5.0, 5.5)
    assert stratified_bootstrap_ci(scores, np.mean, reps=REPS, confidence=0.45) == (5.25, 5.25, 5.25)


def test_the_bootstrap_is_seeded_and_its_seed_matters():
    scores = np.random.default_rng(1).normal(size=(5, 3))
    a = stratified_bootstrap_ci(scores, iqm, reps=300, rng_seed=0)
    assert stratified_bootstrap_ci(scores, iqm, reps=300, rng_seed=0) == a
    assert stratified_bootstrap_ci(scores, iqm, reps=300, rng_seed=1) != a
    assert stratified_bootstrap_ci(scores, iqm, reps=300) == a  # seed 0 by default


def test_a_single_bootstrap_sample_is_allowed_and_none_is_refused():
    assert stratified_bootstrap_ci(np.array([[2.0, 4.0]]), np.mean, reps=1) == (3.0, 3.0, 3.0)
    with pytest.raises(ValueError, match=r"^reps must be >= 1, got 0$"):
        stratified_bootstrap_ci(np.array([[2.0, 4.0]]), np.mean, reps=0)


@pytest.mark.parametrize("confidence", [0.0, 1.0, -0.5, 1.5])
def test_a_confidence_outside_zero_to_one_is_refused(confidence):
    with pytest.raises(ValueError, match=rf"^confidence must be in \(0, 1\), got {confidence}$"):
        stratified_bootstrap_ci(np.array([[0.0], [1.0]]), np.mean, reps=10, confidence=confidence)
    with pytest.raises(ValueError, match=rf"^confidence must be in \(0, 1\), got {confidence}$"):
        probability_of_improvement_ci(np.array([[0.0]]), np.array([[1.0]]), reps=10, confidence=confidence)


@pytest.mark.parametrize(
    ("scores", "message"),
    [
        (np.array([1.0, 2.0]), r"^scores must be a non-empty \[runs, tasks\] matrix, got shape \(2,\)$"),
        (np.zeros((0, 2)), r"^scores must be a non-empty \[runs, tasks\] matrix, got shape \(0, 2\)$"),
        (np.zeros((2, 0)), r"^scores must be a non-empty \[runs, tasks\] matrix, got shape \(2, 0\)$"),
        (np.zeros((1, 1, 1)), r"^scores must be a non-empty \[runs, tasks\] matrix, got shape \(1, 1, 1\)$"),
        (np.array([[1.0, np.nan]]), r"^scores holds NaN or infinite scores: drop those tasks first$"),
        (np.array([[1.0, np.inf]]), r"^scores holds NaN or infinite scores: drop those tasks first$"),
    ],
)
def test_a_score_matrix_that_is_not_a_finite_runs_by_tasks_matrix_is_refused(scores, message):
    with pytest.raises(ValueError, match=message):
        stratified_bootstrap_ci(scores, np.mean, reps=10)
    with pytest.raises(ValueError, match=message.replace("scores", "x", 1)):
        probability_of_improvement(scores, np.ones((1, 2)))


# --------------------------------------------------------------------------------------------- probability of improvement


def test_probability_of_improvement_by_hand_on_three_tasks():
    """x (2 runs) against y (3 runs), lower is better, ties half:
    task 0: x {1, 4} vs y {2, 3, 4}: 1 beats all three (3), 4 beats none and ties one (0.5): 3.5 / 6;
    task 1: x {5, 5} vs y {5, 5, 5}: all ties: 0.5;  task 2: x {9, 9} vs y {1, 2, 3}: 0.
    Average over tasks: (3.5/6 + 0.5 + 0) / 3."""
    x = np.array([[1.0, 5.0, 9.0], [4.0, 5.0, 9.0]])
    y = np.array([[2.0, 5.0, 1.0], [3.0, 5.0, 2.0], [4.0, 5.0, 3.0]])
    assert probability_of_improvement(x, y) == pytest.approx((3.5 / 6 + 0.5 + 0.0) / 3, rel=1e-12)
    assert probability_of_improvement(y, x) == pytest.approx(1.0 - (3.5 / 6 + 0.5 + 0.0) / 3, rel=1e-12)


def test_probability_of_improvement_needs_the_same_tasks():
    with pytest.raises(ValueError, match=r"^x and y must have the same tasks \(columns\), got 3 and 2$"):
        probability_of_improvement(np.ones((2, 3)), np.ones((1, 2)))
    with pytest.raises(ValueError, match=r"^y must be a non-empty"):
        probability_of_improvement(np.ones((2, 3)), np.ones((0, 3)))


def test_the_improvement_interval_resamples_the_candidates_runs():
    """x runs {0, 2} against one baseline run at 1: both resampled runs 0 → 1, both 2 → 0, mixed → 1/2 (ties none),
    so 95 % → (0, 1) and 45 % → (1/2, 1/2); the point is 1/2."""
    x, y = np.array([[0.0], [2.0]]), np.array([[1.0]])
    assert probability_of_improvement_ci(x, y, reps=REPS) == (0.5, 0.0, 1.0)
    assert probability_of_improvement_ci(x, y, reps=REPS, confidence=0.45) == (0.5, 0.5, 0.5)
    assert probability_of_improvement_ci(x, y, reps=REPS, confidence=0.6) == (0.5, 0.0, 1.0)


def test_the_improvement_interval_resamples_the_comparisons_runs_too():
    """One candidate run at 2 against y runs {1, 3}: y resampled {1, 1} → 0, {3, 3} → 1, mixed → 1/2."""
    x, y = np.array([[2.0]]), np.array([[1.0], [3.0]])
    assert probability_of_improvement_ci(x, y, reps=REPS) == (0.5, 0.0, 1.0)
    assert probability_of_improvement_ci(x, y, reps=REPS, confidence=0.45) == (0.5, 0.5, 0.5)


def test_the_improvement_interval_is_seeded_and_needs_a_sample():
    """1000 samples: three chunks of 256 and one of 232; every sample is a probability in [0, 1]."""
    rng = np.random.default_rng(2)
    x, y = rng.normal(size=(4, 3)), rng.normal(size=(3, 3))
    a = probability_of_improvement_ci(x, y, reps=1000)
    assert a == probability_of_improvement_ci(x, y, reps=1000, rng_seed=0)
    assert a != probability_of_improvement_ci(x, y, reps=1000, rng_seed=1)
    assert 0.0 <= a[1] <= a[0] <= a[2] <= 1.0 and a[0] == probability_of_improvement(x, y)
    assert probability_of_improvement_ci(x - 10.0, y, reps=1) == (1.0, 1.0, 1.0)  # every sample: certain gain
    with pytest.raises(ValueError, match=r"^reps must be >= 1, got 0$"):
        probability_of_improvement_ci(x, y, reps=0)


# --------------------------------------------------------------------------------------------- episodes


def _row(run, controller, suite, scenario, seed, dev, force=1.0, time=10.0):
    return {"run": run, "controller": controller, "suite": suite, "scenario": scenario, "seed": seed,
            "deviation_mean_mm": dev, "lateral_force_max_n": force, "drill_time_s": time}  # fmt: skip


def test_normalising_reads_runs_as_text_seeds_as_integers_and_bad_metrics_as_nan():
    raw = pd.DataFrame(
        [
            _row(np.nan, "base", "paper", "paper", 1.0, "0.5", time="failed"),
            _row("seed3", "policy", "paper", "paper", 2, 0.25, time=12),
        ]
    ).drop(columns="lateral_force_max_n")
    before = raw.copy()
    frame = normalise_episodes(raw)
    assert frame["run"].tolist() == ["", "seed3"] and frame["seed"].tolist() == [1, 2]
    assert frame["seed"].dtype.kind == "i"
    assert frame["deviation_mean_mm"].tolist() == [0.5, 0.25]
    assert math.isnan(frame["drill_time_s"][0]) and frame["drill_time_s"][1] == 12.0
    assert frame["lateral_force_max_n"].isna().all()  # a missing metric column is NaN
    for metric in ("deviation_mean_mm", "lateral_force_max_n", "drill_time_s"):
        assert frame[metric].dtype == np.float64
    pd.testing.assert_frame_equal(raw, before)  # the caller's frame is left alone


def test_normalising_baselines_only_reads_their_empty_runs_as_text():
    """After a CSV round trip a frame of baselines alone has a float ``run`` column of NaN (and a numbered run
    reads back as a float)."""
    raw = pd.DataFrame([_row(np.nan, "base", "paper", "paper", 0, 1.0), _row(3.0, "base", "paper", "paper", 1, 1.0)])
    assert raw["run"].dtype == np.float64
    assert normalise_episodes(raw)["run"].tolist() == ["", "3.0"]


def test_normalising_names_the_missing_columns():
    with pytest.raises(ValueError, match=r"^episodes lack the columns \['scenario', 'seed'\]$"):
        normalise_episodes(pd.DataFrame({"run": [""], "controller": ["a"], "suite": ["paper"]}))


def test_the_score_matrix_has_every_scenario_of_the_suite_and_runs_in_natural_order():
    """Scenarios of the suite from any controller (c only has a baseline episode: the policy's cell is NaN);
    runs seed2 before seed10; each cell the mean over its seeds, a failed (NaN) episode left out."""
    rows = [
        _row("seed10", "policy", "heldout", "b", 0, 1.0),
        _row("seed10", "policy", "heldout", "b", 1, 2.0),
        _row("seed2", "policy", "heldout", "b", 0, 4.0),
        _row("seed2", "policy", "heldout", "a", 0, 0.5),
        _row("seed2", "policy", "heldout", "a", 1, np.nan),
        _row("seed10", "policy", "heldout", "a", 0, 3.0),
        _row("", "base", "heldout", "c", 0, 9.0),
        _row("seed2", "policy", "paper", "paper", 0, 7.0),  # another suite: not counted
    ]
    scores, runs, tasks = score_matrix(pd.DataFrame(rows), "policy", "heldout", "deviation_mean_mm")
    assert runs == ["seed2", "seed10"] and tasks == ["a", "b", "c"]
    np.testing.assert_array_equal(scores, [[0.5, 4.0, np.nan], [3.0, 1.5, np.nan]])
    none, no_runs, same_tasks = score_matrix(pd.DataFrame(rows), "other", "heldout", "deviation_mean_mm")
    assert none.shape == (0, 3) and no_runs == [] and same_tasks == ["a", "b", "c"]


def _pairs(policy: dict, base: dict, suite: str = "heldout") -> pd.DataFrame:
    rows = [_row("seed0", "policy", suite, sc, s, v) for (sc, s), v in policy.items()]
    rows += [_row("", "base", suite, sc, s, v) for (sc, s), v in base.items()]
    rows += [_row("seed1", "policy", suite, sc, s, 100.0) for (sc, s) in policy]  # another run: not paired
    return pd.DataFrame(rows)


def test_the_paired_difference_is_a_student_t_interval_on_the_pairs_by_hand():
    """Pairs (a, 0..2): differences −1, 0, −2 (a missing baseline episode (a, 3) and a failed policy one (b, 0)
    are dropped): mean −1, SD 1, half-width t(0.975, 2) · 1 / √3 = 2.4841; at 90 %, t(0.95, 2) / √3 = 1.6859."""
    policy = {("a", 0): 1.0, ("a", 1): 3.0, ("a", 2): 2.0, ("a", 3): 5.0, ("b", 0): np.nan}
    base = {("a", 0): 2.0, ("a", 1): 3.0, ("a", 2): 4.0, ("b", 0): 1.0, ("b", 1): 1.0}
    frame = _pairs(policy, base)
    got = paired_diff(frame, "seed0", "policy", "base", "heldout", "deviation_mean_mm")
    half = T975_DF2 / math.sqrt(3.0)
    assert got["n"] == 3 and got["dropped"] == 3  # (a, 3) no baseline, (b, 0) failed, (b, 1) no policy
    assert got["mean"] == -1.0 and got["policy_mean"] == 2.0 and got["baseline_mean"] == 3.0
    assert (got["low"], got["high"]) == pytest.approx((-1.0 - half, -1.0 + half), rel=1e-12)
    at90 = paired_diff(frame, "seed0", "policy", "base", "heldout", "deviation_mean_mm", confidence=0.9)
    assert (at90["low"], at90["high"]) == pytest.approx((-1.0 - T95_DF2 / math.sqrt(3), -1.0 + T95_DF2 / math.sqrt(3)))
    only_b = paired_diff(frame, "seed0", "policy", "base", "heldout", "deviation_mean_mm", scenario="b")
    assert only_b["n"] == 0 and only_b["dropped"] == 2 and math.isnan(only_b["mean"]) and math.isnan(only_b["low"])
    assert math.isnan(only_b["policy_mean"]) and math.isnan(only_b["baseline_mean"])
    assert set(got) == {"mean", "low", "high", "n", "dropped", "policy_mean", "baseline_mean"}


def test_one_pair_has_a_mean_but_no_interval():
    frame = _pairs({("a", 0): 1.5}, {("a", 0): 1.0})
    got = paired_diff(frame, "seed0", "policy", "base", "heldout", "deviation_mean_mm")
    assert got["n"] == 1 and got["mean"] == 0.5 and math.isnan(got["low"]) and math.isnan(got["high"])


def test_identical_pairs_have_a_zero_width_interval():
    frame = _pairs({("a", 0): 1.5, ("a", 1): 2.5}, {("a", 0): 1.0, ("a", 1): 2.0})
    got = paired_diff(frame, "seed0", "policy", "base", "heldout", "deviation_mean_mm")
    assert (got["mean"], got["low"], got["high"]) == (0.5, 0.5, 0.5)


def test_two_episodes_of_the_same_specimen_on_one_side_are_refused():
    frame = _pairs({("a", 0): 1.0}, {("a", 0): 2.0})
    twice = pd.concat([frame, frame[frame["controller"] == "base"].assign(deviation_mean_mm=2.5)])
    with pytest.raises(
        ValueError, match=r"^base has several episodes with the same \(scenario, seed\) in suite heldout$"
    ):
        paired_diff(twice, "seed0", "policy", "base", "heldout", "deviation_mean_mm")
    twice = pd.concat([frame, frame[frame["run"] == "seed0"].assign(deviation_mean_mm=0.5)])
    with pytest.raises(ValueError, match=r"^policy seed0 has several episodes"):
        paired_diff(twice, "seed0", "policy", "base", "heldout", "deviation_mean_mm")
