"""The pair rule's bars and the guards (pairs.py) on both sides, with stub scores and hand-built gap terms.

The bars are written out as docs/diagnosis.md states them: a pair beats the best single in ≥ 95 % of the
resamples and removes ≥ 50 % of the excess gap the single leaves; its second effect alone removes ≥ 30 % of what
it adds; on the cells only the second effect reaches, the first must surely (≥ 95 %) leave a gap and the pair surely
lower it by ≥ 50 % of the excess. "Exactly on a bar" uses 100 score draws of which exactly 95 are better (95 / 100
is the float 0.95) and gaps whose differences are exact in binary; "just off" is one draw or 1e-7 off.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pytest
from diagnosis_stubs import stub_score

import drillgym.eval.diagnosis.pairs as pairs
from drillgym.eval.diagnosis.channels import ALL_CHANNELS, GROUP_OF, STAGES
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.pairs import (
    _cell_gaps,
    _OwnCellGaps,
    own_cells,
    pair_improves,
    pair_roles,
    possible_second_effects,
    second_effect_evidence,
    second_stands_alone,
    single_contradicted,
)
from drillgym.eval.diagnosis.rank import ModelScore

BETTER, WORSE = 40.0, 60.0
"""Score draws of a model better or worse than one whose draws are all 50."""


def _draws(better: int, tied: int = 0) -> np.ndarray:
    """100 score draws: ``better`` of them below 50, ``tied`` at 50, the rest above."""
    k = np.arange(100)
    return np.where(k < better, BETTER, np.where(k < better + tied, 50.0, WORSE))


def _model(names: tuple[str, ...], after: float, draws: np.ndarray | None = None, before: float = 11.0) -> ModelScore:
    return stub_score(names, before, after, 1.0, np.full(100, 50.0) if draws is None else draws)


# -- pair_improves ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("better", "pair_after", "improves"),
    [
        (95, 3.0, True),  # better in exactly 95 % of the resamples, removes exactly half of the 4 left
        (94, 3.0, False),  # one resample short
        (95, 3.0 + 1e-7, False),  # removes just under half
    ],
)
def test_a_pair_improves_on_the_single_when_surely_better_and_removing_half_of_what_it_leaves(
    better, pair_after, improves
):
    """The single leaves 5 against the simulator's own 1: 4 to remove."""
    single = _model(("a",), 5.0)
    assert pair_improves(_model(("a", "b"), pair_after, _draws(better)), single, 1.0) is improves


def test_a_single_that_leaves_nothing_above_the_simulators_level_cannot_be_improved_on():
    single = _model(("a",), 1.0)
    assert pair_improves(_model(("a", "b"), 0.5, _draws(100)), single, 1.0) is False


# -- second_stands_alone ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(("second_after", "alone"), [(2.0, True), (2.0 + 1e-7, False)])
def test_a_second_effect_stands_alone_when_alone_it_removes_30_percent_of_what_it_adds(second_after, alone):
    """First alone leaves 11, the pair 1: the second adds 10; alone (5 before) it must remove 3."""
    first, pair = _model(("a",), 11.0), _model(("a", "b"), 1.0)
    second = _model(("b",), second_after, before=5.0)
    assert second_stands_alone(pair, first, second) is alone


def test_a_second_effect_that_adds_nothing_or_was_not_fitted_alone_does_not_stand_alone():
    first, strong = _model(("a",), 5.0), _model(("b",), 1.0, before=11.0)
    assert second_stands_alone(_model(("a", "b"), 5.0), first, strong) is False  # adds 0
    assert second_stands_alone(_model(("a", "b"), 1.0), first, None) is False


# -- own cells and roles ---------------------------------------------------------------------------------------------

TORQUE = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "torque"]
FORCE = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "force"]
Q = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "q"]
APPROACH, STABLE = STAGES.index("approach"), STAGES.index("stable")


def test_own_cells_of_an_unknown_effect_on_either_side_are_unknown():
    assert own_cells("ft_drift", "warp_drive") is None and own_cells("warp_drive", "ft_drift") is None


def test_own_cells_before_contact_keep_the_cells_of_the_cut():
    """Runout (force and torque in the cut, nothing before contact) on top of an F/T drift (force, also before
    contact): its own cells are the torque in every stage, the approach included."""
    mask = own_cells("ft_drift", "tool_runout")
    assert mask is not None and mask[:, TORQUE].all() and mask.sum() == len(STAGES) * len(TORQUE)


def test_a_pairs_roles_when_a_single_is_missing_or_the_two_tie():
    a, b = _model(("a",), 5.0), _model(("b",), 6.0)
    pair = _model(("a", "b"), 1.0)
    assert pair_roles(pair, {"b": b}) == (None, b)
    assert pair_roles(pair, {"a": a}) == (a, None)
    tie = _model(("b",), 5.0)
    tie.score = a.score
    first, second = pair_roles(pair, {"a": a, "b": tie})
    assert first is a and second is tie  # a tie keeps the pair's own order


# -- gaps on a set of cells ------------------------------------------------------------------------------------------


def _gaps(first_over: int, first_tied: int, pair_under: int, pair_tied: int, first=5.0, pair=3.0, null=1.0):
    """Own-cell gaps: the first's draws above the null's in ``first_over`` of 100 (``first_tied`` equal), the pair's
    below the first's in ``pair_under`` (``pair_tied`` equal)."""
    k = np.arange(100)
    null_draws = np.full(100, 1.0)
    first_draws = np.where(k < first_over, 2.0, np.where(k < first_over + first_tied, 1.0, 0.5))
    pair_draws = np.where(k < pair_under, first_draws - 0.25, np.where(k < pair_under + pair_tied, first_draws, 9.0))
    return _OwnCellGaps(first, pair, null, first_draws, pair_draws, null_draws)


@pytest.mark.parametrize(
    ("gaps", "removed"),
    [
        (_gaps(95, 0, 95, 0), True),  # each exactly on its bar: 95 %, 95 %, (5 − 3) / (5 − 1) = 50 %
        (_gaps(94, 1, 95, 0), False),  # the first above the null in 94 %, a tie not counted
        (_gaps(95, 0, 94, 1), False),  # the pair below the first in 94 %, a tie not counted
        (_gaps(50, 0, 100, 0), False),  # the first not surely above the null, however well the pair does
        (_gaps(95, 0, 95, 0, pair=3.5), False),  # removes (5 − 3.5) / 4 = 37.5 %
        (_gaps(100, 0, 100, 0, first=1.0, pair=0.5), False),  # the first at the null level: nothing to remove
    ],
)
def test_the_pair_removes_the_gap_on_its_own_cells_only_past_every_bar(gaps, removed):
    assert gaps.removed() is removed


@pytest.mark.parametrize(("worse", "worsened"), [(95, True), (94, False)])
def test_the_pair_worsens_its_own_cells_when_above_the_first_in_95_percent_of_the_resamples(worse, worsened):
    k = np.arange(100)
    first_draws = np.full(100, 2.0)
    pair_draws = np.where(k < worse, 3.0, 2.0)  # above in ``worse``, tied in the rest (a tie is not worse)
    assert _OwnCellGaps(2.0, 3.0, 1.0, first_draws, pair_draws, np.ones(100)).worsened() is worsened


def _cells(values: list[tuple[float, float]], cell: tuple[int, int] = (APPROACH, 2)) -> list[Terms]:
    """Episodes with ``(sum of terms, number of terms)`` in one cell (approach, fz_n by default)."""
    out = []
    for j, n in values:
        s, c = np.zeros(N_CELLS), np.zeros(N_CELLS)
        s[cell], c[cell] = j, n
        out.append(Terms(s, c, np.zeros(N_CELLS)))
    return out


MASK = np.zeros(N_CELLS, dtype=bool)
MASK[APPROACH, 2] = True


def test_cell_gaps_are_pooled_over_the_masked_cells_with_every_episode_in_the_resamples():
    """First 2 and 6 over one term each (pooled 4; resampled: 2, 4 or 6), pair 1, null 1 over 2 terms."""
    first, pair, null = _cells([(2.0, 1.0), (6.0, 1.0)]), _cells([(1.0, 1.0)] * 2), _cells([(1.0, 2.0)] * 2)
    g = _cell_gaps(first, pair, null, MASK)
    assert g is not None and (g.first, g.pair, g.null) == (4.0, 1.0, 0.5)
    assert set(g.first_draws) == {2.0, 4.0, 6.0} and set(g.pair_draws) == {1.0} and set(g.null_draws) == {0.5}
    assert len(g.first_draws) == 1000


def test_cell_gaps_are_reproducible_from_their_seed_zero_by_default():
    rng = np.random.default_rng(3)
    first = _cells([(v, 1.0) for v in rng.uniform(1, 9, 8)])
    pair, null = _cells([(1.0, 1.0)] * 8), _cells([(1.0, 1.0)] * 8)
    default, zero, one = (_cell_gaps(first, pair, null, MASK, *s) for s in ((), (0,), (1,)))
    assert default is not None and zero is not None and one is not None
    assert np.array_equal(default.first_draws, zero.first_draws)
    assert not np.array_equal(zero.first_draws, one.first_draws)


def test_cell_gaps_of_one_episode_are_that_episodes():
    g = _cell_gaps(_cells([(3.0, 1.0)]), _cells([(2.0, 1.0)]), _cells([(1.0, 1.0)]), MASK)
    assert g is not None and (g.first, g.pair, g.null) == (3.0, 2.0, 1.0)


@pytest.mark.parametrize(
    ("first", "pair", "null", "mask"),
    [
        ([(2.0, 1.0)], [(1.0, 1.0)], [(1.0, 1.0)], None),  # no cells known
        ([(2.0, 1.0)], [(1.0, 1.0)], [(1.0, 1.0)], np.zeros(N_CELLS, dtype=bool)),  # no cells
        ([], [], [], MASK),  # no episodes
        ([(2.0, 1.0)], [(1.0, 1.0)] * 2, [(1.0, 1.0)], MASK),  # the pair's terms of another set of episodes
        ([(2.0, 1.0)] * 2, [(1.0, 1.0)], [(1.0, 1.0)], MASK),  # the first's
        ([(0.0, 0.0)], [(1.0, 1.0)], [(1.0, 1.0)], MASK),  # the first has no terms there
        ([(2.0, 1.0)], [(1.0, 1.0)], [(0.0, 0.0)], MASK),  # the null has none
    ],
)
def test_no_cell_gaps_without_cells_terms_or_matching_episodes(first, pair, null, mask):
    assert _cell_gaps(_cells(first), _cells(pair), _cells(null), mask) is None


def test_a_resample_of_episodes_without_terms_on_the_cells_is_nan_without_a_warning():
    first, pair, null = _cells([(0.0, 0.0), (2.0, 1.0)]), _cells([(0.0, 0.0), (1.0, 1.0)]), _cells([(1.0, 1.0)] * 2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        g = _cell_gaps(first, pair, null, MASK)
    assert g is not None and np.isnan(g.first_draws).any() and set(g.first_draws[~np.isnan(g.first_draws)]) == {2.0}


class _Recorder:
    """Stands for a bootstrap: records the seed it is given, answers ``answer``."""

    def __init__(self, answer: Any) -> None:
        self.answer, self.seeds = answer, []

    def __call__(self, *args: Any, **kw: Any) -> Any:
        self.seeds.append(kw["seed"] if "seed" in kw else args[-1])
        return self.answer


@pytest.mark.parametrize("rule", [pairs.second_on_own_cells, pairs.second_contradicted])
def test_the_own_cell_rules_pass_their_seed_to_the_bootstrap_zero_by_default(monkeypatch, rule):
    rec = _Recorder(None)
    monkeypatch.setattr(pairs, "_own_cell_gaps", rec)
    a, ab = _model(("a",), 5.0), _model(("a", "b"), 1.0)
    assert rule(ab, a, []) is False and rule(ab, a, [], 7) is False
    assert rec.seeds == [0, 7]


def test_the_before_contact_guard_and_the_own_cell_gaps_pass_their_seed_zero_by_default(monkeypatch):
    rec = _Recorder(None)
    monkeypatch.setattr(pairs, "_cell_gaps", rec)
    drift, ab = _model(("ft_drift",), 5.0), _model(("ft_drift", "latency"), 1.0)
    assert single_contradicted(drift, [], []) is False and single_contradicted(drift, [], [], 7) is False
    assert pairs._own_cell_gaps(ab, drift, []) is None and pairs._own_cell_gaps(ab, drift, [], seed=5) is None
    assert rec.seeds == [0, 7, 0, 5]


def test_the_before_contact_guard_is_for_single_effects_only():
    pair = _model(("ft_drift", "latency"), 1.0)
    worse = _cells([(9.0, 1.0)] * 4)  # far worse before contact than the data
    pair.fit.ho_terms = worse
    assert single_contradicted(pair, _cells([(1.0, 1.0)] * 4), _cells([(1.0, 1.0)] * 4)) is False


# -- the evidence in diagnosis.json ----------------------------------------------------------------------------------

Q0 = (STABLE, Q[0])


def _with_terms(names: tuple[str, ...], after: float, terms: list[Terms], draws: np.ndarray | None = None):
    s = _model(names, after, draws)
    s.fit.ho_terms = terms
    return s


def test_the_evidence_of_effects_without_declared_cells_has_none():
    """Unknown effects: no own cells, so no gaps there; the second alone removes 3 of the 4 it adds."""
    first, pair = _model(("x",), 5.0), _model(("x", "y"), 1.0)
    second = _model(("y",), 8.0)
    assert second_effect_evidence(pair, first, second, _cells([(1.0, 1.0)])) == {
        "second": "y",
        "alone": True,
        "own_cells": False,
        "contradicted": False,
        "own_groups": [],
        "own_gap_first": None,
        "own_gap_pair": None,
        "own_gap_null": None,
    }


def test_the_evidence_of_a_second_effect_that_worsens_its_own_cells():
    """A joint friction on top of an entry friction: its own cells are the joint angles (and the tracker before
    contact); there the first leaves 2, the pair 4, the simulator 1 in every episode."""
    null = _cells([(1.0, 1.0)] * 4, Q0)
    first = _with_terms(("skid_friction",), 5.0, _cells([(2.0, 1.0)] * 4, Q0))
    pair = _with_terms(("skid_friction", "joint_friction"), 1.0, _cells([(4.0, 1.0)] * 4, Q0))
    assert second_effect_evidence(pair, first, None, null) == {
        "second": "joint_friction",
        "alone": False,
        "own_cells": False,
        "contradicted": True,
        "own_groups": ["q", "tracker"],
        "own_gap_first": 2.0,
        "own_gap_pair": 4.0,
        "own_gap_null": 1.0,
    }


# -- possible second effects -----------------------------------------------------------------------------------------


def test_a_possible_second_effect_is_listed_with_its_pair_whatever_comes_before_it_in_the_scores():
    named, hidden = _model(("a",), 5.0), _model(("h",), 10.9)
    ah = _model(("a", "h"), 1.2, _draws(100))
    other_order = _model(("h", "a"), 1.3, _draws(100))
    ak = _model(("a", "k"), 1.4, _draws(100))
    got = possible_second_effects([named, hidden, ah, other_order, ak], named, 1.0)
    assert got == [
        {"name": "a+h", "second": "h", "heldout_gap_after": 1.2, "p_better": 1.0},
        {"name": "a+k", "second": "k", "heldout_gap_after": 1.4, "p_better": 1.0},
    ]


def test_a_second_effect_shown_on_its_own_cells_is_not_merely_possible():
    """The pair removes the gap the entry friction leaves on the joint angles (5 → 1, the simulator's own 1): a
    second effect, though alone (not fitted here) it shows nothing. Without the null terms only "alone" is judged."""
    null = _cells([(1.0, 1.0)] * 4, Q0)
    named = _with_terms(("skid_friction",), 5.0, _cells([(5.0, 1.0)] * 4, Q0))
    pair = _with_terms(("skid_friction", "joint_friction"), 1.0, _cells([(1.0, 1.0)] * 4, Q0), _draws(100))
    assert possible_second_effects([pair, named], named, 1.0, null) == []
    assert [x["second"] for x in possible_second_effects([pair, named], named, 1.0)] == ["joint_friction"]


# -- a second effect shown on its own cells ---------------------------------------------------------------------------


TRACKER_X = ALL_CHANNELS.index("tracker_x_task_m")


@pytest.mark.parametrize(("better", "beats"), [(95, True), (94, False)])
def test_a_second_effect_shown_on_its_own_cells_needs_the_pair_only_surely_better(better, beats):
    """A stick-out error leaves 5 (the simulator's own level is 1) and the offset on top removes only a quarter of
    it (5 → 4): below the bar of half. But on the tracker before contact, where only the offset acts, the first
    leaves 5 in every episode and the pair 1: shown there, the pair is named when better in 95 % of the resamples."""
    null = _cells([(1.0, 1.0)] * 4, (APPROACH, TRACKER_X))
    first = _with_terms(("tool_length",), 5.0, _cells([(5.0, 1.0)] * 4, (APPROACH, TRACKER_X)))
    pair = _with_terms(
        ("tool_length", "kinematic_offset"), 4.0, _cells([(1.0, 1.0)] * 4, (APPROACH, TRACKER_X)), _draws(better)
    )
    assert not pair_improves(pair, first, 1.0)
    assert pairs.pair_beats(pair, first, first, None, 1.0, null) is beats
    assert not pairs.pair_beats(pair, first, first, None, 1.0)  # without the null terms: the plain rule only


def test_a_second_effect_without_a_gap_on_its_own_cells_still_needs_half_of_what_the_first_leaves():
    """The first leaves nothing above the simulator's level on the tracker before contact: the offset on top is
    not shown there, and removing a quarter of the rest is not enough."""
    null = _cells([(1.0, 1.0)] * 4, (APPROACH, TRACKER_X))
    first = _with_terms(("tool_length",), 5.0, _cells([(1.0, 1.0)] * 4, (APPROACH, TRACKER_X)))
    pair = _with_terms(
        ("tool_length", "kinematic_offset"), 4.0, _cells([(1.0, 1.0)] * 4, (APPROACH, TRACKER_X)), _draws(100)
    )
    assert not pairs.pair_beats(pair, first, first, None, 1.0, null)
