"""Interval coverage against the candidate's best equivalent of a reality (its fit on many fresh episodes)."""

from __future__ import annotations

import json

from drillgym.eval.diagnosis.bench.cases import Case, full_cases
from drillgym.eval.diagnosis.bench.pseudo_truth import jobs_for, load_or_compute
from drillgym.eval.diagnosis.bench.run import add_best_equivalent, summarise


def _row(spec: str, effect: str, param: str, truth: float, low: float, high: float) -> dict:
    check = {"effect": effect, "param": param, "truth": truth, "fit": 0.5 * (low + high), "low": low, "high": high}
    check["covered"] = low <= truth <= high
    return {
        "case": spec,
        "kind": "single",
        "spec": spec,
        "truth": [effect],
        "named": [effect],
        "correct": True,
        "top1_ranked": True,
        "true_effect_shrink": 0.9,
        "verdict": "explained",
        "params": [check],
    }


def test_intervals_are_scored_against_the_best_equivalent_where_there_is_one():
    rows = [
        _row("tracker_smoothing:tau_s=0.15", "tracker_latency", "latency_s", 0.15, 0.135, 0.139),
        _row("episode_warmup:fz_n=3,spread_n=5", "ft_episode_drift", "fz_rate_n_s", 0.009, 0.004, 0.012),
        _row("wobbly_runout:runout_m=4e-5", "tool_runout", "runout_m", 4e-5, 4.7e-5, 4.8e-5),
    ]
    table = {
        "tracker_smoothing:tau_s=0.15": {"candidate": "tracker_latency", "params": {"latency_s": 0.137}},
        "wobbly_runout:runout_m=4e-5": {"candidate": "tool_runout", "params": {"runout_m": 4.9e-5}},
        # the shared drift's best equivalent is not the random effect's mean: that is the written population mean
        "episode_warmup:fz_n=3,spread_n=5": {"candidate": "ft_drift", "params": {"fz_rate_n_s": 0.02}},
    }
    add_best_equivalent(rows, table)
    checks = [r["params"][0] for r in rows]
    assert [c["best_equivalent"] for c in checks] == [0.137, 0.009, 4.9e-5]  # a random effect's mean: the truth
    assert [c["covered_best_equivalent"] for c in checks] == [True, True, False]
    figures = summarise(rows)["figures"]
    assert figures["interval_coverage"] == 1 / 3 and figures["interval_coverage_best_equivalent"] == 2 / 3
    assert figures["parameters_scored_best_equivalent"] == 3


def test_best_equivalents_are_fitted_once_per_reality_and_kept_in_the_file(tmp_path):
    cases = [c for c in full_cases() if c.name.startswith("tracker_smoothing")]
    assert [j[0] for j in jobs_for(cases)] == [c.spec for c in cases]
    assert jobs_for([c for c in full_cases() if c.name.startswith("episode_warmup")]) == []  # random effect
    strong = [c for c in cases if c.name.endswith("strong")]
    path = tmp_path / "pseudo_truth.json"
    table = load_or_compute(path, strong, workers=1, episodes=6)
    entry = table[strong[0].spec]
    assert entry["candidate"] == "tracker_latency" and not entry["error"] and entry["episodes"] == 6
    # A 150 ms first-order filter reads as a shorter delay: it has not reached its steady lag on the short
    # stretches of constant speed (docs/diagnosis.md §3).
    assert 0.12 < entry["params"]["latency_s"] < 0.15
    assert json.loads(path.read_text()) == json.loads(json.dumps(table))
    again = load_or_compute(path, [*strong, Case("x", "clean", "none", 0)], workers=1, episodes=6)
    assert again == json.loads(path.read_text())  # read back, nothing refitted


def test_a_file_that_is_not_a_table_is_a_one_line_error_before_any_work(tmp_path, capsys):
    from drillgym.eval.cli import main

    bad = tmp_path / "pt.json"
    for text in ("{not json", '{"spec": {"params": {}}}', "[1, 2]"):
        bad.write_text(text)
        code = main(["bench-diagnosis", "--quick", "--out", str(tmp_path / "out"), "--pseudo-truth", str(bad)])
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.startswith("drillgym bench-diagnosis: error: ") and "not a pseudo-truth table" in err
        assert bad.read_text() == text and not (tmp_path / "out").exists()  # nothing overwritten, nothing run
