"""Where the gap lies (where.gap_map, where.locate) and a model's entry in diagnosis.json (ModelScore.to_json).

Terms are built by hand in a few cells; the expected maps are written out cell by cell. Comparisons are exact: every
value is a quotient or square root of small exactly representable numbers chosen to come out exact.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import ModelScore
from drillgym.eval.diagnosis.where import gap_map, locate

APPROACH, ENTRY1, STABLE = (STAGES.index(s) for s in ("approach", "entry1", "stable"))
FZ, TX, Q0 = (ALL_CHANNELS.index(c) for c in ("fz_n", "tx_nm", "q0_rad"))


def _terms(cells: dict[tuple[int, int], tuple[float, float, float]]) -> Terms:
    """One episode: ``{(stage, channel): (sum of terms, number of terms, sum of squared raw gaps)}``."""
    s, n, r = np.zeros(N_CELLS), np.zeros(N_CELLS), np.zeros(N_CELLS)
    for cell, (j, k, rms) in cells.items():
        s[cell], n[cell], r[cell] = j, k, rms
    return Terms(s, n, r)


REAL = [
    _terms({(STABLE, FZ): (6.0, 2.0, 6.0), (ENTRY1, TX): (3.0, 1.0, 1.0)}),
    _terms({(STABLE, FZ): (2.0, 2.0, 10.0), (APPROACH, Q0): (5.0, 1.0, 4.0)}),
]
"""Summed: (stable, fz_n) 8 over 4 terms, raw 16; (entry1, tx_nm) 3 over 1, raw 1; (approach, q0_rad) 5 over 1, raw 4."""
NULL = [
    _terms({(STABLE, FZ): (1.0, 1.0, 0.0), (ENTRY1, TX): (0.5, 1.0, 0.0)}),
    _terms({(STABLE, FZ): (1.0, 1.0, 0.0)}),
]
"""The simulator's own level: 1 per term at (stable, fz_n), 0.5 at (entry1, tx_nm) (one term), none elsewhere."""


def _map(cells: dict[tuple[int, int], float], elsewhere: float | None) -> list[list[float | None]]:
    """A channel × stage table holding ``cells`` (keyed (stage, channel)) and ``elsewhere`` in every other cell."""
    return [[cells.get((s, c), elsewhere) for s in range(len(STAGES))] for c in range(len(ALL_CHANNELS))]


def test_the_gap_map_is_the_mean_term_the_null_level_the_raw_rms_and_the_excess_per_channel_and_stage():
    """Per cell: normalised = Σ J / Σ N (none without terms); null = the null's Σ J / Σ N (none without null terms);
    rms = √(Σ raw² / Σ N); excess = Σ J − Σ N · null level, the null level 0 where the null has no terms. Cells without
    terms (0 / 0) are computed silently."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = gap_map(REAL, NULL)
    assert got["channels"] == list(ALL_CHANNELS) and got["stages"] == list(STAGES)
    assert got["normalised"] == _map({(STABLE, FZ): 2.0, (ENTRY1, TX): 3.0, (APPROACH, Q0): 5.0}, None)
    assert got["null"] == _map({(STABLE, FZ): 1.0, (ENTRY1, TX): 0.5}, None)
    assert got["rms"] == _map({(STABLE, FZ): 2.0, (ENTRY1, TX): 1.0, (APPROACH, Q0): 2.0}, None)
    assert got["excess"] == _map({(STABLE, FZ): 4.0, (ENTRY1, TX): 2.5, (APPROACH, Q0): 5.0}, 0.0)
    assert set(got) == {"channels", "stages", "normalised", "null", "rms", "excess"}


def test_the_gap_map_entries_are_plain_floats_for_json():
    got = gap_map(REAL, NULL)
    assert type(got["normalised"][FZ][STABLE]) is float and type(got["excess"][0][0]) is float


def test_the_cells_with_the_most_excess_come_first_with_their_share_of_the_positive_excess():
    """Excess 4, 2.5 and 5 over the summed null level (as in the map), and −2 at (stable, tx_nm) (below the null:
    clipped to 0, so not in the total): shares 5 / 11.5, 4 / 11.5, 2.5 / 11.5."""
    below = _terms({(STABLE, TX): (0.0, 2.0, 0.0)})
    null = [*NULL, _terms({(STABLE, TX): (2.0, 2.0, 0.0)})]
    got = locate([*REAL, below], null)
    assert got == [
        {"channel": "q0_rad", "stage": "approach", "share": 5.0 / 11.5},
        {"channel": "fz_n", "stage": "stable", "share": 4.0 / 11.5},
        {"channel": "tx_nm", "stage": "entry1", "share": 2.5 / 11.5},
    ]
    assert locate([*REAL, below], null, top=1) == got[:1]
    assert [c["channel"] for c in locate(REAL, NULL, top=4)][:3] == ["q0_rad", "fz_n", "tx_nm"]
    assert len(locate(REAL, NULL, top=4)) == 4


def test_without_any_excess_the_shares_are_zero_not_a_division_by_zero():
    same = locate(NULL, NULL, top=2)
    assert [c["share"] for c in same] == [0.0, 0.0]


@pytest.fixture
def score() -> ModelScore:
    fit = FitResult(
        names=("latency", "ft_drift"),
        params=[{"extra_latency_s": 0.02}, {"fz_rate_n_s": 0.01}],
        n_params=4,
        cal_objective=1.5,
        evaluations=120,
        replays=80,
        wall_s=3.25,
        error="",
        penalty_params=2.5,
        per_episode={"spread": {}},
    )
    intervals = {"latency": {"extra_latency_s": {"low": 0.01, "high": 0.03}}, "ft_drift": {"fz_rate_n_s": None}}
    return ModelScore(
        fit,
        before=5.0,
        after=1.25,
        shrink=0.9375,
        ci_low=0.75,
        ci_high=0.99,
        score=42.0,
        leftover_ratio=2.5,
        p_best=0.625,
        named=True,
        intervals=intervals,
    )


def test_a_models_json_entry_holds_its_effects_fit_and_held_out_numbers(score):
    assert score.to_json() == {
        "name": "latency+ft_drift",
        "effects": ["latency", "ft_drift"],
        "params": {"latency": {"extra_latency_s": 0.02}, "ft_drift": {"fz_rate_n_s": 0.01}},
        "param_intervals": {
            "latency": {"extra_latency_s": {"low": 0.01, "high": 0.03}},
            "ft_drift": {"fz_rate_n_s": None},
        },
        "n_params": 4,
        "penalty_params": 2.5,
        "per_episode": {"spread": {}},
        "heldout_gap_before": 5.0,
        "heldout_gap_after": 1.25,
        "shrink": 0.9375,
        "leftover_ratio": 2.5,
        "ci_low": 0.75,
        "ci_high": 0.99,
        "score": 42.0,
        "p_best": 0.625,
        "named": True,
        "shape": None,
        "fit": {"calibration_gap": 1.5, "evaluations": 120, "replays": 80, "wall_s": 3.25, "error": ""},
    }


def test_a_json_entry_is_a_new_list_of_effects_and_reports_a_failed_fit(score):
    score.fit.error = "replay failed"
    entry = score.to_json()
    assert entry["effects"] is not score.fit.names and entry["fit"]["error"] == "replay failed"
    assert entry["name"] == "latency+ft_drift"


def test_a_fit_whose_parameters_do_not_match_its_effects_has_no_json_entry(score):
    score.fit.params = score.fit.params[:1]
    with pytest.raises(ValueError, match="zip"):
        score.to_json()
