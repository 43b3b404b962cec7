"""The rule that names a pair of effects over the best single one."""

from __future__ import annotations

import numpy as np
from diagnosis_stubs import stub_score

from drillgym.eval.diagnosis.pairs import pair_beats
from drillgym.eval.diagnosis.rank import ModelScore

NULL_GAP = 1.0


def _score(names: tuple[str, ...], before: float, after: float, draws: float) -> ModelScore:
    rng = np.random.default_rng(len(names))
    return stub_score(names, before, after, NULL_GAP, draws + rng.normal(0.0, 0.01 * draws, 500))


def test_two_real_effects_that_add_up_are_named_as_a_pair():
    a = _score(("a",), 11.0, 5.0, 500.0)  # a alone removes 6 of 10
    b = _score(("b",), 11.0, 7.0, 700.0)  # b alone removes 4
    ab = _score(("a", "b"), 11.0, 1.2, 120.0)  # together almost all
    assert pair_beats(ab, best=a, first=a, second=b, null_gap=NULL_GAP)


def test_an_effect_that_only_helps_alongside_another_is_not_a_second_effect():
    a = _score(("a",), 11.0, 5.0, 500.0)
    patch = _score(("p",), 11.0, 10.9, 1090.0)  # alone it does nothing
    ap = _score(("a", "p"), 11.0, 1.2, 120.0)
    assert not pair_beats(ap, best=a, first=a, second=patch, null_gap=NULL_GAP)


def test_a_pair_must_remove_half_of_what_the_best_single_leaves():
    a = _score(("a",), 11.0, 5.0, 500.0)
    b = _score(("b",), 11.0, 7.0, 700.0)
    ab = _score(("a", "b"), 11.0, 3.5, 350.0)  # removes 1.5 of the 4 left: not enough
    assert not pair_beats(ab, best=a, first=a, second=b, null_gap=NULL_GAP)


def test_a_pair_built_on_the_second_best_single_is_judged_against_the_best():
    a = _score(("a",), 11.0, 5.0, 500.0)  # the best single
    b = _score(("b",), 11.0, 6.0, 600.0)
    c = _score(("c",), 11.0, 8.0, 800.0)
    bc = _score(("b", "c"), 11.0, 1.5, 150.0)  # c adds 4.5 on top of b; alone c removes 3 (≥ 30 %)
    assert pair_beats(bc, best=a, first=b, second=c, null_gap=NULL_GAP)
    worse = _score(("b", "c"), 11.0, 4.8, 480.0)  # better than b, but not surely better than a
    assert not pair_beats(worse, best=a, first=b, second=c, null_gap=NULL_GAP)


def test_a_second_effect_hidden_behind_the_first_is_reported_as_possible_not_named():
    from drillgym.eval.diagnosis.pairs import possible_second_effects

    a = _score(("a",), 11.0, 5.0, 500.0)
    hidden = _score(("h",), 11.0, 10.9, 1090.0)  # alone it explains nothing visible
    ah = _score(("a", "h"), 11.0, 1.2, 120.0)
    real = _score(("b",), 11.0, 7.0, 700.0)
    ab = _score(("a", "b"), 11.0, 1.3, 130.0)
    useless = _score(("a", "u"), 11.0, 4.99, 499.5)  # adds nothing on top
    possible = possible_second_effects([ah, ab, a, useless, hidden, real], a, NULL_GAP)
    assert [x["second"] for x in possible] == ["h"] and possible[0]["p_better"] > 0.95
    assert possible_second_effects([ah, a, hidden], ah, NULL_GAP) == []  # a named pair has no "second"


def test_the_effect_a_pair_adds_to_its_stronger_single_must_be_shown_whichever_came_first():
    from drillgym.eval.diagnosis.pairs import pair_roles
    from drillgym.eval.diagnosis.rank import singles_by_name

    # Forward selection built (weak, strong): a weak first effect with the real one fitted on top, which then
    # "adds" all it explains alone. Judged that way round it passes; what the pair adds to the strong single is
    # the weak one, which alone removes 0.3 of the 2.5 it adds there (a patch on the strong effect's form).
    weak = _score(("w",), 11.0, 10.7, 1070.0)
    strong = _score(("s",), 11.0, 4.0, 400.0)
    pair = _score(("w", "s"), 11.0, 1.5, 150.0)
    assert pair_beats(pair, best=strong, first=weak, second=strong, null_gap=NULL_GAP)
    first, second = pair_roles(pair, singles_by_name([strong, weak, pair]))
    assert (first, second) == (strong, weak)
    assert not pair_beats(pair, best=strong, first=first, second=second, null_gap=NULL_GAP)
    # Two real effects pass either way round.
    a, b = _score(("a",), 11.0, 5.0, 500.0), _score(("b",), 11.0, 7.0, 700.0)
    ba = _score(("b", "a"), 11.0, 1.2, 120.0)
    assert pair_roles(ba, singles_by_name([a, b])) == (a, b)
    assert pair_beats(ba, best=a, first=a, second=b, null_gap=NULL_GAP)


def test_a_possible_second_effect_is_found_whichever_order_its_pair_was_built_in():
    from drillgym.eval.diagnosis.pairs import possible_second_effects

    a = _score(("a",), 11.0, 5.0, 500.0)
    hidden = _score(("h",), 11.0, 10.9, 1090.0)
    ha = _score(("h", "a"), 11.0, 1.2, 120.0)  # built on h, with the named a fitted on top
    ah = _score(("a", "h"), 11.0, 1.3, 130.0)  # the same pair the other way round, a little worse
    possible = possible_second_effects([ha, ah, a, hidden], a, NULL_GAP)
    assert [(x["name"], x["second"]) for x in possible] == [("h+a", "h")]  # once, with its better pair
