"""The acceptance rules (:mod:`drillgym.eval.learning.seed_checks`) on both sides of every bar, by hand.

Each fixture pairs the policy with the best baseline on 4 episode seeds per scenario; the per-episode
differences are ``m ± S`` (alternating, S = 2⁻⁷), so every figure is known by hand: mean m, SD S·√(4/3), and a
95 % Student-t half-width t(0.975, 3) · S / √3 = 1.8374 S = 0.01435 for one scenario (4 pairs) or
t(0.975, 7) · S / √7 = 0.8937 S = 0.00698 for two pooled scenarios (8 pairs). The values are binary fractions,
so the differences are exact; each bar is approached to within 0.0007 to 0.0013 (a tenth of a half-width) from
both sides, far beyond float rounding (1e-16) and close enough that a rule read as a mean comparison, or a
CI bound swapped, fails. Lower is better for every metric.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.learning.seed_checks import CHECK_COLUMNS, RULES, run_checks, seed_checks
from drillgym.eval.learning.seed_stats import normalise_episodes

S = 2.0**-7
HALF_1 = 3.1824463052837078 * S / math.sqrt(3.0)  # one scenario, 4 pairs: t(0.975, 3) = 3.1824
HALF_2 = 2.364624251592784 * S / math.sqrt(7.0)  # two scenarios pooled, 8 pairs: t(0.975, 7) = 2.3646
BEST, REF = "tuned", "li2023"
SIGNIFICANT_1 = 2.0**-6  # 0.0156 > HALF_1 = 0.0144: a mean this far from 0 has a CI on its side
STRADDLING_1 = 2.0**-6 - 2.0**-9  # 0.0137 < HALF_1: same sign of the mean, CI across 0
SIGNIFICANT_2 = 2.0**-7  # 0.0078 > HALF_2 = 0.0070
STRADDLING_2 = 2.0**-7 - 2.0**-9  # 0.0059 < HALF_2


def _frame(
    paper: float = -SIGNIFICANT_1,
    force: float = 0.0,
    force_spread: float = S,
    general: float = -SIGNIFICANT_2,
    held: tuple[float, float] = (-SIGNIFICANT_1, -SIGNIFICANT_1),
    time_ratio: float = 1.25,
    reference_mm: float = 2.0,
    runs: tuple[str, ...] = ("seed0",),
    suites: tuple[str, ...] = ("paper", "generalisation", "heldout"),
) -> pd.DataFrame:
    """Best baseline 1.0 mm, 1.0 N, 10 s everywhere; the reference ``reference_mm`` on the paper scenario; each
    policy run's episode = baseline + (mean difference ± S), its drill time ``time_ratio`` times the baseline's."""
    cells = {"paper": [("paper", paper)], "generalisation": [("g0", general), ("g1", general)]}
    cells["heldout"] = [("h0", held[0]), ("h1", held[1])]
    rows = []
    for suite in suites:
        for scenario, m in cells[suite]:
            for seed in range(4):
                sign = (-1.0) ** seed
                common = {"suite": suite, "scenario": scenario, "seed": seed}
                rows.append({**common, "run": "", "controller": BEST, "deviation_mean_mm": 1.0,
                             "lateral_force_max_n": 1.0, "drill_time_s": 10.0})  # fmt: skip
                rows.append({**common, "run": "", "controller": REF, "deviation_mean_mm": reference_mm,
                             "lateral_force_max_n": 1.5, "drill_time_s": 8.0})  # fmt: skip
                for run in runs:
                    f = force + force_spread * sign if suite == "paper" else 0.0
                    rows.append({**common, "run": run, "controller": "policy", "deviation_mean_mm": 1.0 + m + S * sign,
                                 "lateral_force_max_n": 1.0 + f, "drill_time_s": 10.0 * time_ratio})  # fmt: skip
    return pd.DataFrame(rows)


def _row(**kw) -> pd.Series:
    return seed_checks(_frame(**kw), BEST, REF).iloc[0]


def _failing(row: pd.Series) -> set[str]:
    return {rule for rule in RULES if not row[rule]}


def test_a_run_clearly_better_everywhere_passes_every_rule_with_the_hand_figures():
    row = _row()
    assert _failing(row) == set() and bool(row["passes"]) and row["notes"] == ""
    assert row["paper_deviation_mean"] == -SIGNIFICANT_1 and row["paper_deviation_n"] == 4
    assert row["paper_deviation_high"] == pytest.approx(-SIGNIFICANT_1 + HALF_1, rel=1e-9)
    assert row["paper_deviation_low"] == pytest.approx(-SIGNIFICANT_1 - HALF_1, rel=1e-9)
    assert row["paper_force_mean"] == 0.0 and row["paper_force_high"] == pytest.approx(HALF_1, rel=1e-9)
    assert row["generalisation_deviation_n"] == 8
    assert row["generalisation_deviation_high"] == pytest.approx(-SIGNIFICANT_2 + HALF_2, rel=1e-9)
    assert row["heldout_deviation_n"] == 8 and row["heldout_deviation_mean"] == -SIGNIFICANT_1
    assert row["heldout_worse_scenarios"] == []
    assert row["paper_deviation_vs_reference_pct"] == pytest.approx(100.0 * ((1.0 - SIGNIFICANT_1) / 2.0 - 1.0))
    assert row["paper_time_vs_best_pct"] == pytest.approx(25.0, rel=1e-12)
    assert all(row[f"{p}_dropped"] == 0 for p in ("paper_deviation", "paper_force", "heldout_deviation"))


def test_a_lower_paper_deviation_whose_ci_straddles_zero_is_not_better():
    assert _failing(_row(paper=-STRADDLING_1)) == {"paper_better"}
    row = _row(paper=-STRADDLING_1)
    assert row["paper_deviation_mean"] < 0.0 < row["paper_deviation_high"] and not row["passes"]
    assert _failing(_row(paper=0.0)) == {"paper_better"}  # no difference at all: CI high = HALF_1 > 0


def test_equal_paper_deviations_on_every_pair_are_not_better():
    """All four differences 0: the CI is [0, 0] and "better" needs its top below 0."""
    frame = _frame()
    frame.loc[(frame["controller"] == "policy") & (frame["suite"] == "paper"), "deviation_mean_mm"] = 1.0
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert row["paper_deviation_high"] == 0.0 and not row["paper_better"]


def test_a_higher_paper_force_passes_while_its_ci_reaches_zero_and_fails_once_it_is_significant():
    row = _row(force=STRADDLING_1)
    assert row["paper_force_mean"] > 0.0 > row["paper_force_low"] and row["paper_force_ok"] and row["passes"]
    assert _failing(_row(force=SIGNIFICANT_1)) == {"paper_force_ok"}
    exact = _row(force=0.0, force_spread=0.0)  # four equal forces: CI [0, 0], low = 0 is "not higher"
    assert exact["paper_force_low"] == 0.0 and exact["paper_force_ok"]
    assert _row(force=-SIGNIFICANT_1)["paper_force_ok"]  # lower is fine


def test_the_generalisation_gain_must_have_its_pooled_ci_below_zero():
    assert _failing(_row(general=-STRADDLING_2)) == {"generalisation_better"}
    row = _row(general=-STRADDLING_2)
    assert row["generalisation_deviation_mean"] < 0.0 < row["generalisation_deviation_high"]
    assert _row(general=-SIGNIFICANT_2)["generalisation_better"]


def test_the_heldout_mean_over_scenarios_must_be_below_zero_not_at_it():
    """h0 −2⁻⁸ and h1 +2⁻⁸: pooled mean exactly 0 (not better); h0 a further 2⁻¹² lower: better. Neither scenario
    is significantly worse (2⁻⁸ < HALF_1)."""
    tie = _row(held=(-(2.0**-8), 2.0**-8))
    assert tie["heldout_deviation_mean"] == 0.0 and _failing(tie) == {"heldout_better"}
    better = _row(held=(-(2.0**-8) - 2.0**-12, 2.0**-8))
    assert better["heldout_deviation_mean"] < 0.0 and _failing(better) == set()


def test_a_heldout_scenario_or_generalisation_pool_equal_on_every_pair_is_neither_worse_nor_better():
    """All differences 0: CI [0, 0]. "Worse" needs CI low > 0 and "better" CI high < 0, so neither holds."""
    frame = _frame()
    policy = frame["controller"] == "policy"
    frame.loc[policy & frame["scenario"].isin(["h1", "g0", "g1"]), "deviation_mean_mm"] = 1.0
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert row["heldout_worse_scenarios"] == [] and row["heldout_none_worse"]
    assert row["generalisation_deviation_high"] == 0.0 and not row["generalisation_better"]


def test_a_single_heldout_pair_counts_as_heldout_data_with_no_scenario_worse():
    """One heldout pair: its scenario's CI is NaN (one pair has none), so it is not worse, and the suite has data."""
    frame = _frame()
    keep = (frame["controller"] != "policy") | (frame["suite"] != "heldout") | (frame["seed"] == 0)
    frame = frame[keep & ~((frame["controller"] == "policy") & (frame["scenario"] == "h1"))]
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert row["heldout_deviation_n"] == 1 and math.isnan(row["heldout_deviation_low"])
    assert row["heldout_none_worse"] and row["heldout_better"]


def test_one_heldout_scenario_significantly_worse_fails_even_when_the_pool_is_better():
    worse = _row(held=(-0.25, SIGNIFICANT_1))
    assert worse["heldout_worse_scenarios"] == ["h1"] and worse["heldout_better"]
    assert _failing(worse) == {"heldout_none_worse"} and not worse["passes"]
    close = _row(held=(-0.25, STRADDLING_1))  # worse on average but its CI reaches 0: not "worse"
    assert close["heldout_worse_scenarios"] == [] and close["heldout_none_worse"]
    both = _row(held=(SIGNIFICANT_1 + 0.25, SIGNIFICANT_1))
    assert both["heldout_worse_scenarios"] == ["h0", "h1"]


@pytest.mark.parametrize(("reference_mm", "passes"), [(1.41, True), (1.40, False)])
def test_the_paper_deviation_must_be_30_percent_below_the_references(reference_mm, passes):
    """Policy 1 − 2⁻⁶ = 0.984 mm: against 1.41 mm −30.2 %, against 1.40 mm −29.7 %."""
    row = _row(reference_mm=reference_mm)
    assert row["paper_deviation_vs_reference_pct"] == pytest.approx(100.0 * (0.984375 / reference_mm - 1.0))
    assert bool(row["beats_reference_30pct"]) is passes and _failing(row) == (
        set() if passes else {"beats_reference_30pct"}
    )


@pytest.mark.parametrize(("ratio", "passes"), [(1.29, True), (1.31, False), (0.5, True)])
def test_the_paper_drill_time_may_be_at_most_30_percent_longer(ratio, passes):
    row = _row(time_ratio=ratio)
    assert row["paper_time_vs_best_pct"] == pytest.approx(100.0 * (ratio - 1.0), rel=1e-9)
    assert bool(row["time_ok"]) is passes and _failing(row) == (set() if passes else {"time_ok"})


def test_a_missing_suite_gives_nan_figures_false_checks_and_a_note():
    row = _row(suites=("paper", "heldout"))
    assert math.isnan(row["generalisation_deviation_mean"]) and row["generalisation_deviation_n"] == 0
    assert _failing(row) == {"generalisation_better"}
    assert row["notes"] == "generalisation suite missing: its checks are NaN/False"
    row = _row(suites=("generalisation", "heldout"))
    assert _failing(row) == {"paper_better", "paper_force_ok", "beats_reference_30pct", "time_ok"}  # all paper rules
    assert row["notes"] == "paper suite missing: its checks are NaN/False"
    assert math.isnan(row["paper_deviation_vs_reference_pct"]) and math.isnan(row["paper_time_vs_best_pct"])


def test_a_suite_without_the_policys_episodes_or_with_failed_ones_is_noted():
    frame = _frame()
    frame = frame[~((frame["controller"] == "policy") & (frame["suite"] == "heldout"))]
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert _failing(row) == {"heldout_better", "heldout_none_worse"}  # no pairs: not "none worse" either
    assert row["notes"] == (
        "no paired heldout deviation episodes: its checks are NaN/False; "
        "heldout: 8 failed or unpaired deviation pairs dropped"
    )
    frame = _frame()
    failed = (frame["controller"] == "policy") & (frame["suite"] == "paper") & (frame["seed"] == 0)
    frame.loc[failed, "deviation_mean_mm"] = np.nan
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert row["paper_deviation_n"] == 3 and row["paper_deviation_dropped"] == 1
    assert row["notes"] == "paper: 1 failed or unpaired deviation pairs dropped"


def test_every_run_is_checked_alone_in_natural_order_with_the_documented_columns():
    frame = _frame(runs=("seed10", "seed2"))
    slow = (frame["run"] == "seed10") & (frame["suite"] == "paper")
    frame.loc[slow, "drill_time_s"] = 20.0
    checks = seed_checks(frame, BEST, REF)
    assert list(checks.columns) == list(CHECK_COLUMNS)
    assert checks["run"].tolist() == ["seed2", "seed10"]
    assert checks["passes"].tolist() == [True, False]
    assert checks["paper_time_vs_best_pct"].tolist() == pytest.approx([25.0, 100.0])
    direct = run_checks(normalise_episodes(frame), "seed2", BEST, REF)
    assert direct == checks.iloc[0].to_dict()


def test_the_reference_is_li2023_by_default():
    frame = _frame(reference_mm=1.40)  # the policy is only −29.7 % below li2023: fails if li2023 is the reference
    assert not seed_checks(frame, BEST).iloc[0]["beats_reference_30pct"]
    assert seed_checks(frame, BEST).equals(seed_checks(frame, BEST, "li2023"))


def test_a_frame_without_policy_runs_gives_no_rows_but_the_documented_columns():
    frame = _frame()
    checks = seed_checks(frame[frame["controller"] != "policy"], BEST, REF)
    assert len(checks) == 0 and list(checks.columns) == list(CHECK_COLUMNS)


def test_a_zero_baseline_gives_no_relative_figure():
    frame = _frame()
    frame.loc[frame["controller"] == BEST, "drill_time_s"] = 0.0
    row = seed_checks(frame, BEST, REF).iloc[0]
    assert math.isnan(row["paper_time_vs_best_pct"]) and not row["time_ok"]
