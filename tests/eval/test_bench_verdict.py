"""``drillgym bench --reference`` and the verdicts and warnings of its report."""

import pandas as pd
import pytest

from drillgym.eval.bench.jobs import reference_spec
from drillgym.eval.bench.report import few_seeds_warning
from drillgym.eval.cli import main


def bench(out, *extra):
    return main(["bench", "--controllers", "none,li2023", "--seeds", "2", "--no-logs", "--out", str(out), *extra])


def test_reference_changes_the_baseline_of_the_paired_differences(tmp_path, capsys):
    assert bench(tmp_path / "first") == 0
    assert bench(tmp_path / "ref", "--reference", "li2023") == 0
    first = pd.read_csv(tmp_path / "first" / "paired.csv")
    ref = pd.read_csv(tmp_path / "ref" / "paired.csv")
    assert set(first.baseline) == {"none"} and set(first.controller) == {"li2023"}
    assert set(ref.baseline) == {"li2023"} and set(ref.controller) == {"none"}
    pd.testing.assert_series_equal(ref["mean"], -first["mean"])  # the same pairs, the other way round
    pd.testing.assert_frame_equal(  # the episodes do not depend on the reference
        pd.read_csv(tmp_path / "first" / "episodes.csv").drop(columns="wall_time_s"),
        pd.read_csv(tmp_path / "ref" / "episodes.csv").drop(columns="wall_time_s"),
    )
    md = (tmp_path / "ref" / "summary.md").read_text()
    assert "## Paired differences vs `li2023`" in md and "reference `li2023`" in md
    # li2023 compensates the deflection: without it the deviation is far higher, on both seeds
    verdict = "deviation_mean_mm: `none` higher than `li2023` ("
    assert f"* {verdict}" in md and "mm, CI excludes 0)" in md
    assert "| paper | `none` | 2 | **" in md  # the significant difference in bold
    out = capsys.readouterr().out
    assert out.rstrip().splitlines()[-1].startswith("Results: ")
    assert f"  {verdict}" in out.split("Verdicts vs `li2023`")[-1]  # printed again at the end


def test_reference_accepts_a_spec_or_its_label_and_lists_the_choices_otherwise():
    specs = ["none", "li2023:kp=1.0"]
    assert reference_spec(specs, None) == "none"
    assert reference_spec(specs, "li2023:kp=1.0") == reference_spec(specs, "li2023_kp-1.0") == "li2023:kp=1.0"
    with pytest.raises(ValueError, match=r"'zhang2005'.*choose from none, li2023:kp=1.0, li2023_kp-1.0"):
        reference_spec(specs, "zhang2005")


def test_an_unknown_reference_is_an_error_before_any_episode_runs(tmp_path, capsys):
    assert bench(tmp_path / "bench", "--reference", "zhang2005") == 2
    err = capsys.readouterr().err
    assert "drillgym bench: error: --reference 'zhang2005' is not one of the --controllers" in err
    assert "choose from none, li2023" in err
    assert not (tmp_path / "bench").exists()


def test_fewer_than_20_seeds_warn_on_stderr_and_in_the_summary(tmp_path, capsys):
    assert main(["bench", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", str(tmp_path)]) == 0
    warning = "fewer than 20 seeds per scenario: the 95 % CIs are wide"
    assert f"drillgym bench: warning: {warning}" in capsys.readouterr().err
    md = (tmp_path / "summary.md").read_text()
    assert f"Warning: {warning}" in md
    assert "## Verdicts" not in md  # one controller: nothing to compare
    assert few_seeds_warning(19) and few_seeds_warning(20) == ""
