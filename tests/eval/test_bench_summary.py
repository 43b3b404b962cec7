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
