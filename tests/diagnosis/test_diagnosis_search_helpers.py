"""The search's bookkeeping in diagnose.py on stub fits: which pairs are refitted and from where, a single's best
fit found anywhere, an effect switched off, parameter intervals, fits collected in order.

Fits and scores are built by hand (no simulator); the expected jobs, values and samples are written out.
"""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from drillgym.eval.diagnosis.context import make_spec
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.rank import ModelScore

dg = importlib.import_module("drillgym.eval.diagnosis.diagnose")  # the module (the package exports the function)

S0 = 100.0
"""Penalised score of "no effect"."""


def _fit(names, params=None, cal=1.0, error="", samples=()):
    names = tuple(names)
    params = params if params is not None else [{"v": float(len(n))} for n in names]
    return FitResult(names, params, len(names), cal_objective=cal, error=error, samples=list(samples))


def _score(fit: FitResult, score: float, nameable: bool = True) -> ModelScore:
    """A scored model, nameable against S0 unless ``nameable`` is False (then it removes 10 % only)."""
    shrink = 0.8 if nameable else 0.1
    return ModelScore(fit, before=5.0, after=1.0, shrink=shrink, ci_low=0.6, ci_high=0.9, score=score)


A = _fit(["a"], [{"p": 1.0}])
B = _fit(["b"], [{"q": 2.0}])
C = _fit(["c"], [{"r": 3.0}])


def _pairs():
    """Forward fits: (a, b), (b, a), (a, c), (c, b); (b, c) failed."""
    return [
        _fit(["a", "b"], [{"p": 1.1}, {"q": 2.1}]),
        _fit(["b", "a"], [{"q": 2.2}, {"p": 1.2}]),
        _fit(["a", "c"], [{"p": 1.3}, {"r": 3.3}]),
        _fit(["c", "b"], [{"r": 3.4}, {"q": 2.4}]),
        _fit(["b", "c"], [{}, {}], error="replay failed"),
    ]


def test_no_refits_when_none_are_asked_for():
    pairs = _pairs()
    scores = [_score(p, 10.0 + k) for k, p in enumerate(pairs[:4])] + [_score(A, 20.0), _score(B, 30.0)]
    assert dg._refit_jobs(scores, pairs, S0, 0) == []
    assert dg._refit_jobs(scores, pairs, S0, -1) == []


def test_the_best_pairs_are_refitted_from_their_forward_fit_the_other_order_and_the_singles_side_by_side():
    pairs = _pairs()
    ab, ba, ac, cb, _ = pairs
    # the two best nameable singles are b and a (c is not nameable): their pair (b, a) is among the best already
    scores = [
        _score(ba, 5.0),
        _score(cb, 6.0),
        _score(ac, 7.0),
        _score(B, 20.0),
        _score(A, 30.0),
        _score(C, 40.0, False),
    ]
    jobs = dg._refit_jobs(scores, pairs, S0, 2)
    assert jobs == [
        (("b", "a"), [[{"q": 2.2}, {"p": 1.2}], [{"q": 2.1}, {"p": 1.1}], [{"q": 2.0}, {"p": 1.0}]], 1),
        (("c", "b"), [[{"r": 3.4}, {"q": 2.4}], [{"r": 3.0}, {"q": 2.0}]], 3),  # no (b, c) forward fit: it failed
    ]
    assert ab.params == [{"p": 1.1}, {"q": 2.1}]  # the forward fits are not changed


def test_the_pair_of_the_two_best_nameable_singles_is_refitted_too():
    pairs = _pairs()
    ab, _, ac, cb, _ = pairs
    # (a, c) and (c, b) score best; the two best nameable singles are a and b (c is not nameable)
    scores = [
        _score(ac, 5.0),
        _score(cb, 6.0),
        _score(C, 15.0, nameable=False),
        _score(A, 20.0),
        _score(B, 30.0),
        _score(ab, 50.0),
    ]
    jobs = dg._refit_jobs(scores, pairs, S0, 2)
    assert [(names, i) for names, _, i in jobs] == [(("a", "c"), 2), (("c", "b"), 3), (("a", "b"), 0)]
    assert jobs[2][1] == [[{"p": 1.1}, {"q": 2.1}], [{"p": 1.2}, {"q": 2.2}], [{"p": 1.0}, {"q": 2.0}]]


def test_the_two_best_nameable_singles_are_judged_against_no_effects_score():
    pairs = _pairs()
    ab, _, ac, _, _ = pairs
    scores = [_score(ac, 5.0), _score(A, 20.0), _score(B, 30.0), _score(ab, 50.0)]
    assert [j[0] for j in dg._refit_jobs(scores, pairs, S0, 1)] == [("a", "c"), ("a", "b")]
    assert [j[0] for j in dg._refit_jobs(scores, pairs, 30.0, 1)] == [("a", "c")]  # b does not beat 30


def test_the_singles_pair_is_not_refitted_twice_nor_when_it_was_not_fitted():
    pairs = _pairs()
    ab, _, ac, _, _ = pairs
    scores = [_score(ab, 5.0), _score(ac, 6.0), _score(A, 20.0), _score(B, 30.0)]
    assert [j[0] for j in dg._refit_jobs(scores, pairs, S0, 2)] == [("a", "b"), ("a", "c")]
    c_first = [_score(ac, 6.0), _score(C, 10.0), _score(B, 20.0)]  # the singles' pair (c, b) was fitted
    assert [j[0] for j in dg._refit_jobs(c_first, pairs, S0, 1)] == [("a", "c"), ("c", "b")]
    b_first = [_score(ac, 6.0), _score(B, 10.0), _score(C, 20.0)]  # (b, c) failed: there is no fit to refit
    assert [j[0] for j in dg._refit_jobs(b_first, pairs, S0, 1)] == [("a", "c")]


def test_a_refit_job_without_single_fits_starts_from_the_forward_fits_only():
    pairs = _pairs()
    ab, *_ = pairs
    jobs = dg._refit_jobs([_score(ab, 5.0), _score(A, 20.0)], pairs, S0, 1)  # b's single is not among the scores
    assert jobs == [(("a", "b"), [[{"p": 1.1}, {"q": 2.1}], [{"p": 1.2}, {"q": 2.2}]], 0)]


def test_failed_pairs_are_not_refitted_and_only_pairs_count_as_the_best_pairs():
    pairs = _pairs()
    *_, bc = pairs
    scores = [_score(A, 1.0), _score(bc, 2.0), _score(B, 3.0)]
    assert dg._refit_jobs(scores, pairs, S0, 3) == [
        (("a", "b"), [[{"p": 1.1}, {"q": 2.1}], [{"p": 1.2}, {"q": 2.2}], [{"p": 1.0}, {"q": 2.0}]], 0)
    ]


DRIFT_OFF = {"fx_rate_n_s": 0.0, "fy_rate_n_s": 0.0, "fz_rate_n_s": 0.0}


def _spec(latency: float, drift: dict[str, float] | None = None, first: bool = True):
    if drift is None:
        return make_spec(["latency"], [{"extra_latency_s": latency}])
    names, params = ["latency", "ft_drift"], [{"extra_latency_s": latency}, drift]
    return make_spec(names, params) if first else make_spec(names[::-1], params[::-1])


def _sample(spec, j: float):
    return (spec, np.full(2, j), np.ones(2))


def test_a_single_keeps_its_fit_when_it_failed_or_is_a_pair():
    failed = _fit(["latency"], [{"extra_latency_s": 0.01}], 5.0, error="boom")
    better = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.02}, DRIFT_OFF], 1.0)
    assert dg._best_anywhere(failed, [better]) is failed
    pair = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.01}, DRIFT_OFF], 5.0)
    assert dg._best_anywhere(pair, [better]) is pair


def test_a_single_takes_the_best_of_the_pairs_holding_it_with_the_other_effect_off_in_either_order():
    single = _fit(["latency"], [{"extra_latency_s": 0.01}], 5.0, samples=[_sample(_spec(0.01), 5.0)])
    second = _fit(  # latency second, the drift off: better still
        ["ft_drift", "latency"],
        [DRIFT_OFF, {"extra_latency_s": 0.03}],
        2.0,
        samples=[
            _sample(_spec(0.03, DRIFT_OFF, first=False), 2.0),
            _sample(_spec(0.04, {**DRIFT_OFF, "fz_rate_n_s": 0.01}, first=False), 1.0),  # drift on: not the single's
            _sample(_spec(0.01, DRIFT_OFF, first=False), 5.5),  # the single's own point, evaluated again
        ],
    )
    first = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.02}, DRIFT_OFF], 3.0)
    failed = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.05}, DRIFT_OFF], 0.5, error="boom")
    other = _fit(["tool_runout", "ft_drift"], [{"runout_m": 1e-5}, DRIFT_OFF], 0.1)
    got = dg._best_anywhere(single, [first, second, failed, other])
    assert got is not single and got.names == ("latency",) and got.n_params == single.n_params
    assert got.params == [{"extra_latency_s": 0.03}] and got.cal_objective == 2.0
    assert got.ho_terms is second.ho_terms
    # its own point first (with the pair's later value of it), then the pair's points with the drift off
    assert [(s[0], float(s[1][0])) for s in got.samples] == [(_spec(0.01), 5.5), (_spec(0.03), 2.0)]
    assert single.params == [{"extra_latency_s": 0.01}] and single.cal_objective == 5.0  # the input is not changed


def test_a_pair_only_as_good_as_the_single_or_with_the_other_effect_on_leaves_it():
    single = _fit(["latency"], [{"extra_latency_s": 0.01}], 2.0)
    tied = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.02}, DRIFT_OFF], 2.0)
    on = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.02}, {**DRIFT_OFF, "fy_rate_n_s": 1e-3}], 1.0)
    assert dg._best_anywhere(single, [tied, on]) is single


@pytest.mark.parametrize(
    ("values", "off"),
    [
        ((("fx_rate_n_s", 0.0), ("fy_rate_n_s", 0.0), ("fz_rate_n_s", 0.0)), True),
        ((("fx_rate_n_s", 0.0), ("fy_rate_n_s", -1e-9), ("fz_rate_n_s", 0.0)), False),
        ((), True),  # a parameter not given is at its default
    ],
)
def test_an_effect_is_off_when_every_parameter_is_at_its_default(values, off):
    assert dg._off(("ft_drift", values)) is off


@pytest.mark.parametrize(
    ("values", "off"),
    [
        ((("softening", 0.0),), True),  # work_j not given: at its default of 20 J
        ((("softening", 0.0), ("work_j", 20.0)), True),
        ((("softening", 0.0), ("work_j", 0.0)), False),  # 0 is not thermal_softening's off value for work_j
        ((("softening", 0.1), ("work_j", 20.0)), False),
    ],
)
def test_off_is_each_parameters_own_default_not_zero(values, off):
    assert dg._off(("thermal_softening", values)) is off


def test_intervals_come_from_the_fit_where_it_has_them_else_from_its_samples_and_are_kept_once_set(monkeypatch):
    calls = []

    def intervals(samples, seed):
        calls.append((samples, seed))
        return {"from": {"samples": None}}

    monkeypatch.setattr(dg, "parameter_intervals", intervals)
    own = _fit(["a"])
    own.intervals = {"own": {"x": None}}
    sampled = _fit(["b"], samples=[_sample(_spec(0.01), 1.0)])
    done = _score(_fit(["c"]), 3.0)
    done.intervals = {"set": {"y": None}}
    scores = [_score(own, 1.0), _score(sampled, 2.0), done]
    dg._bound(scores, 7)
    assert [s.intervals for s in scores] == [{"own": {"x": None}}, {"from": {"samples": None}}, {"set": {"y": None}}]
    assert calls == [(sampled.samples, 7)]


def test_two_fits_samples_are_merged_each_point_once_with_the_later_values():
    a = _fit(["latency"], samples=[_sample(_spec(0.01), 1.0), _sample(_spec(0.02), 2.0)])
    b = _fit(["latency"], samples=[_sample(_spec(0.02), 3.0), _sample(_spec(0.03), 4.0)])
    merged = dg._merged_samples(a, b)
    assert [(s[0], float(s[1][0])) for s in merged] == [(_spec(0.01), 1.0), (_spec(0.02), 3.0), (_spec(0.03), 4.0)]


class _Bar:
    def __init__(self) -> None:
        self.n = 0

    def update(self, n: int = 1) -> None:
        self.n += n


def test_fits_arriving_in_any_order_are_collected_in_index_order_one_tick_each():
    x, y, z = _fit(["x"]), _fit(["y"]), _fit(["z"])
    bar = _Bar()
    assert dg._collect(iter([(2, z), (0, x), (1, y)]), 3, bar) == [x, y, z]  # type: ignore[arg-type]
    assert bar.n == 3


def test_a_single_looks_past_failed_unrelated_and_worse_pairs_for_a_better_one():
    single = _fit(["latency"], [{"extra_latency_s": 0.01}], 5.0)
    failed = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.05}, DRIFT_OFF], 0.5, error="boom")
    unrelated = _fit(["tool_runout", "ft_drift"], [{"runout_m": 1e-5}, DRIFT_OFF], 0.1)
    worse = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.04}, DRIFT_OFF], 6.0)
    better = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.02}, DRIFT_OFF], 1.0)
    got = dg._best_anywhere(single, [failed, unrelated, worse, better])
    assert got.params == [{"extra_latency_s": 0.02}] and got.cal_objective == 1.0


def test_of_three_nameable_singles_the_two_best_make_the_extra_refit():
    pairs = _pairs()
    _, _, ac, _, _ = pairs
    scores = [_score(ac, 5.0), _score(A, 20.0), _score(B, 30.0), _score(C, 40.0)]
    assert [j[0] for j in dg._refit_jobs(scores, pairs, S0, 1)] == [("a", "c"), ("a", "b")]


class _Runner:
    """Answers one refit with ``result``; records what it was asked."""

    def __init__(self, result: FitResult) -> None:
        self.result, self.asked = result, []

    def refits(self, data, models):
        self.asked.append((data, models))
        return iter([(0, self.result)])


DATA = object()
"""Stands for the diagnosis's shared data: passed through untouched."""


def test_a_polish_starts_from_the_models_values_in_every_working_fit_holding_its_effects_in_either_order():
    """The pair is refitted from its own values and the other order's (reordered); not from a failed fit holding
    it, nor from a fit missing one of its effects."""
    fit = _fit(["ft_drift", "latency"], [{"fx_rate_n_s": 0.01}, {"extra_latency_s": 0.05}], 2.0)
    other_order = _fit(["latency", "ft_drift"], [{"extra_latency_s": 0.04}, {"fx_rate_n_s": 0.02}], 2.5)
    failed = _fit(["ft_drift", "latency"], [{"fx_rate_n_s": 0.09}, {"extra_latency_s": 0.09}], 0.1, error="boom")
    single = _fit(["latency"], [{"extra_latency_s": 0.07}], 3.0)
    refit = _fit(["ft_drift", "latency"], [{"fx_rate_n_s": 0.015}, {"extra_latency_s": 0.045}], 1.0)
    runner = _Runner(refit)
    got = dg._polish(runner, DATA, fit, [single, fit, failed, other_order], _Bar())
    assert runner.asked == [
        (
            DATA,
            [
                (
                    ("ft_drift", "latency"),
                    [
                        [{"fx_rate_n_s": 0.01}, {"extra_latency_s": 0.05}],
                        [{"fx_rate_n_s": 0.02}, {"extra_latency_s": 0.04}],
                    ],
                )
            ],
        )
    ]
    assert got is refit


def test_a_refit_as_good_as_the_fit_replaces_it():
    fit = _fit(["latency"], [{"extra_latency_s": 0.05}], 2.0)
    tie = _fit(["latency"], [{"extra_latency_s": 0.051}], 2.0)
    assert dg._polish(_Runner(tie), DATA, fit, [fit], _Bar()) is tie
    worse = _fit(["latency"], [{"extra_latency_s": 0.06}], 2.0 + 1e-12)
    assert dg._polish(_Runner(worse), DATA, fit, [fit], _Bar()) is fit


def test_fits_are_run_on_the_diagnosis_data_and_collected_in_job_order():
    x, y = _fit(["x"]), _fit(["y"])
    jobs = [(("x",), None), (("y",), None)]

    class Runner:
        def fits(self, data, asked):
            assert data is DATA and asked is jobs
            return iter([(1, y), (0, x)])

    bar = _Bar()
    assert dg._run_fits(Runner(), DATA, jobs, bar) == [x, y] and bar.n == 2  # type: ignore[arg-type]
