import math

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.bench.summary import format_ci, mean_ci, paired_differences, summarize


def test_ci_of_the_mean_uses_student_t_with_n_minus_1_dof():
    mean, low, high, n = mean_ci([1.0, 2.0, 3.0])
    half = 4.302652729911275 / math.sqrt(3)  # t(0.975, 2) · s / √n with s = 1
    assert (mean, n) == (2.0, 3)
    assert low == pytest.approx(2.0 - half) and high == pytest.approx(2.0 + half)


def test_ci_equals_scipy_stats_t_interval_bit_for_bit():
    from scipy import stats

    rng = np.random.default_rng(3)
    for n in (2, 3, 5, 20, 100):
        x = rng.normal(1.0, 0.3, n)
        mean, low, high, _ = mean_ci(x)
        half = float(stats.t.ppf(0.975, n - 1)) * float(x.std(ddof=1)) / math.sqrt(n)
        assert (low, high) == (mean - half, mean + half)


def test_ci_of_a_single_value_is_the_value_and_nans_are_left_out():
    for one in ([0.7], [0.7, math.nan]):  # one value: a mean, no interval
        mean, low, high, n = mean_ci(one)
        assert (mean, n) == (0.7, 1) and math.isnan(low) and math.isnan(high)
    assert format_ci(*mean_ci([0.7])[:3]) == "0.7 [–]"
    mean, low, high, n = mean_ci([])
    assert n == 0 and math.isnan(mean) and math.isnan(low) and math.isnan(high)
    assert format_ci(math.nan, math.nan, math.nan) == "-"


def episodes_frame():
    rows = []
    for seed, base in enumerate([1.0, 2.0, 3.0]):
        rows.append({"suite": "s", "scenario": "a", "controller": "none", "seed": seed, "m": base})
        rows.append({"suite": "s", "scenario": "a", "controller": "pid", "seed": seed, "m": base - 0.5 - 0.1 * seed})
    return pd.DataFrame(rows)


def test_paired_differences_pair_episodes_by_seed():
    ep = episodes_frame()
    groups = [("s", "a", "none"), ("s", "a", "pid")]
    paired = paired_differences(ep.sample(frac=1.0, random_state=0), ["m"], groups, baseline="none")
    assert len(paired) == 1
    row = paired.iloc[0]
    assert row["controller"] == "pid" and row["n"] == 3
    assert row["mean"] == pytest.approx(-0.6)
    expected = mean_ci(np.array([-0.5, -0.6, -0.7]))
    assert (row["ci_low"], row["ci_high"]) == pytest.approx(expected[1:3])
    _, low, high, _ = mean_ci(ep.m[ep.controller == "pid"])  # pairing removes the seed-to-seed spread
    assert row["ci_high"] - row["ci_low"] < 0.2 * (high - low)


def test_summary_is_long_form_in_group_order():
    ep = episodes_frame()
    summary = summarize(ep, ["m"], [("s", "a", "pid"), ("s", "a", "none")])
    assert list(summary.columns) == ["suite", "scenario", "controller", "metric", "mean", "ci_low", "ci_high", "n"]
    assert list(summary.controller) == ["pid", "none"]
    assert summary.iloc[1]["mean"] == pytest.approx(2.0)


def test_markdown_cells_are_escaped_so_a_bar_never_splits_a_row():
    from drillgym.eval.bench.summary import md_table

    table = md_table(["a", "b"], [["x | y", "two\nlines"]])
    header, _rule, row = table.splitlines()
    assert row == "| x \\| y | two lines |"
    assert row.replace("\\|", "").count("|") == header.count("|") == 3


def test_rounding_noise_prints_as_zero_in_the_reproduction_report():
    from drillgym.eval.reproduce.report import _fmt

    assert _fmt(3.36e-16) == "0" and _fmt(-2e-14) == "0" and _fmt(0.0123) == "0.0123" and _fmt(None) == "-"


def paired_frame(rows):
    columns = ["suite", "scenario", "controller", "baseline", "metric", "mean", "ci_low", "ci_high", "n"]
    return pd.DataFrame([("s", *r) for r in rows], columns=columns)


def test_a_verdict_names_the_side_only_when_the_ci_excludes_zero():
    from drillgym.eval.bench.summary import significant, verdict

    lower = verdict("deviation_mean_mm", "b", "a", -0.107, -0.115, -0.099, 5)
    assert lower == "deviation_mean_mm: `b` lower than `a` (-0.107 [-0.115, -0.099] mm, CI excludes 0)"
    higher = verdict("lateral_force_max_n", "b", "a", 0.2, 0.05, 0.35, 5)
    assert higher == "lateral_force_max_n: `b` higher than `a` (0.2 [0.05, 0.35] N, CI excludes 0)"
    straddling = verdict("drill_time_s", "b", "a", -0.1, -0.3, 0.1, 5)
    assert (
        straddling == "drill_time_s: no significant difference between `b` and `a` (-0.1 [-0.3, 0.1] s, CI includes 0)"
    )
    assert "no CI" in verdict("deviation_mean_mm", "b", "a", -0.1, math.nan, math.nan, 1)
    assert "no paired episodes" in verdict("deviation_mean_mm", "b", "a", math.nan, math.nan, math.nan, 0)
    assert significant(-0.2, -0.1) and significant(0.1, 0.2)
    assert not significant(-0.1, 0.1) and not significant(0.0, 0.0) and not significant(math.nan, math.nan)


def test_verdict_lines_take_one_scenario_controller_by_controller():
    from drillgym.eval.bench.summary import verdict_lines

    paired = paired_frame(
        [
            ("a", "b", "ref", "m1_mm", -1.0, -1.5, -0.5, 3),
            ("all", "b", "ref", "m1_mm", -1.0, -1.2, -0.8, 6),
            ("all", "b", "ref", "m2_s", 0.1, -0.1, 0.3, 6),
            ("all", "c", "ref", "m1_mm", 0.4, 0.2, 0.6, 6),
        ]
    )
    lines = verdict_lines(paired, ["m1_mm", "m2_s"], "all")
    assert lines == [
        "m1_mm: `b` lower than `ref` (-1 [-1.2, -0.8] mm, CI excludes 0)",
        "m2_s: no significant difference between `b` and `ref` (0.1 [-0.1, 0.3] s, CI includes 0)",
        "m1_mm: `c` higher than `ref` (0.4 [0.2, 0.6] mm, CI excludes 0)",
    ]


def test_significant_paired_differences_are_bold_in_the_markdown_table():
    from drillgym.eval.bench.summary import markdown_table

    paired = paired_frame([("a", "b", "ref", "m1", -1.0, -1.5, -0.5, 3), ("a", "b", "ref", "m2", 0.1, -0.1, 0.3, 3)])
    row = markdown_table(paired, ["m1", "m2"], bold_significant=True).splitlines()[2]
    assert row == "| a | `b` | 3 | **-1 [-1.5, -0.5]** | 0.1 [-0.1, 0.3] |"
    assert "**" not in markdown_table(paired, ["m1", "m2"])
