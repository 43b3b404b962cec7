"""Parameter intervals: a bootstrap over calibration episodes of the points a fit evaluated."""

import math

import numpy as np
import pytest

from drillgym.eval.diagnosis.context import make_spec
from drillgym.eval.diagnosis.intervals import expanded_tail, off_point_inside, parameter_intervals


def _samples(optima: np.ndarray, grid: np.ndarray, param: str = "extra_latency_s", effect: str = "latency"):
    """Episode k's misfit is (x - optima[k])² + 1 per block (10 blocks), evaluated at every grid point."""
    n = np.full(len(optima), 10.0)
    return [(make_spec((effect,), [{param: float(x)}]), 10.0 * ((x - optima) ** 2 + 1.0), n.copy()) for x in grid]


def test_the_interval_of_a_mean_covers_what_a_bootstrap_of_the_episodes_optima_gives():
    rng = np.random.default_rng(3)
    optima = 0.1 + 0.02 * rng.standard_normal(8)  # each episode prefers its own latency
    grid = np.linspace(0.0, 0.3, 3001)
    ci = parameter_intervals(_samples(optima, grid))["latency"]["extra_latency_s"]
    assert ci is not None
    # The pooled fit of a resample is its mean optimum: the interval is the bootstrap of the mean, with the
    # expanded tails of 8 episodes (those of a t interval on 7 degrees of freedom).
    means = [optima[rng.integers(0, 8, 8)].mean() for _ in range(20000)]
    tail = expanded_tail(8)
    low, high = np.quantile(means, [tail, 1 - tail])
    assert abs(ci["low"] - low) < 0.003 and abs(ci["high"] - high) < 0.003
    plain = np.quantile(means, [0.025, 0.975])
    assert ci["low"] < plain[0] and ci["high"] > plain[1]  # wider than the plain percentiles
    assert ci["low"] < optima.mean() < ci["high"] and not ci["contains_off"] and not ci["at_search_edge"]


def test_the_expanded_tails_are_a_t_intervals_on_the_resampled_episodes():
    # Hesterberg (2015): Φ(-sqrt(n/(n-1)) t_{n-1, 0.975}); t_{5, 0.975} = 2.5706 (tables).
    assert expanded_tail(6) == pytest.approx(0.5 * math.erfc(math.sqrt(6 / 5) * 2.5706 / math.sqrt(2)), rel=1e-3)
    assert expanded_tail(6) < expanded_tail(12) < expanded_tail(100) < 0.025
    assert expanded_tail(10**6) == pytest.approx(0.025, abs=1e-4)


def test_an_effect_the_episodes_cannot_tell_from_off_has_the_off_point_inside():
    optima = np.array([0.0, 0.05, -0.04, 0.01, 0.0, -0.02])  # scattered around "no latency"
    grid = np.linspace(0.0, 0.3, 301)  # latency cannot go below 0: the search stops at the off point
    intervals = parameter_intervals(_samples(optima, grid))
    assert intervals["latency"]["extra_latency_s"]["contains_off"]
    assert off_point_inside(intervals, ["latency"]) == ["latency"]


def test_a_parameter_held_by_the_search_has_no_interval_and_is_not_judged():
    n = np.full(4, 10.0)
    samples = [
        (
            make_spec(("latency", "ft_drift"), [{"extra_latency_s": 0.1}, {"fx_rate_n_s": x}]),
            10 * (1 + (x - 0.01) ** 2) * np.ones(4),
            n,
        )
        for x in np.linspace(-0.05, 0.05, 11)
    ]
    intervals = parameter_intervals(samples)
    assert intervals["latency"]["extra_latency_s"] is None
    assert off_point_inside(intervals, ["latency"]) == []


def test_failed_replays_are_left_out():
    optima = np.full(6, 0.1)
    samples = _samples(optima, np.linspace(0.0, 0.3, 31))
    samples.append((make_spec(("latency",), [{"extra_latency_s": 0.2}]), None, None))
    ci = parameter_intervals(samples)["latency"]["extra_latency_s"]
    assert abs(ci["low"] - 0.1) < 1e-9 and abs(ci["high"] - 0.1) < 1e-9


def test_an_interval_narrower_than_the_evaluated_spacing_is_found_between_the_points():
    rng = np.random.default_rng(5)
    optima = 0.1 + 0.002 * rng.standard_normal(8)
    coarse = parameter_intervals(_samples(optima, np.linspace(0.0, 0.3, 31)))["latency"]["extra_latency_s"]
    fine = parameter_intervals(_samples(optima, np.linspace(0.0, 0.3, 3001)))["latency"]["extra_latency_s"]
    # 0.01 between evaluated points; a parabola through a quadratic misfit puts each resample at its exact fit
    assert coarse["high"] - coarse["low"] > 0.001
    assert abs(coarse["low"] - fine["low"]) < 2e-5 and abs(coarse["high"] - fine["high"]) < 2e-5


class _Runner:
    """Answers one refit with a given result and records the starts it was asked to search from."""

    def __init__(self, result):
        self.result, self.asked = result, []

    def refits(self, data, models):
        self.asked.extend(models)
        return iter([(0, self.result)])


class _Bar:
    def update(self, n=1):
        pass


def _fit(names, params, cal, samples=()):
    from drillgym.eval.diagnosis.fit import FitResult

    return FitResult(tuple(names), params, 1, cal_objective=cal, samples=list(samples))


def test_the_named_model_is_refitted_from_its_values_in_the_other_fits_and_keeps_every_evaluated_point():
    from drillgym.eval.diagnosis.diagnose import _polish

    n = np.ones(2)
    p = lambda v: make_spec(("latency",), [{"extra_latency_s": v}])  # noqa: E731
    single = _fit(["latency"], [{"extra_latency_s": 0.08}], 2.0, [(p(0.08), 2 * n, n)])
    pair = _fit(["ft_drift", "latency"], [{"fx_rate_n_s": 0.01}, {"extra_latency_s": 0.05}], 1.5)
    refit = _fit(["latency"], [{"extra_latency_s": 0.051}], 1.2, [(p(0.051), 1.2 * n, n)])
    runner = _Runner(refit)
    out = _polish(runner, None, single, [single, pair], _Bar())
    assert runner.asked == [(("latency",), [[{"extra_latency_s": 0.08}], [{"extra_latency_s": 0.05}]])]
    assert out is refit and {s[0] for s in out.samples} == {p(0.08), p(0.051)}
    worse = _fit(["latency"], [{"extra_latency_s": 0.2}], 3.0, [(p(0.2), 3 * n, n)])
    kept = _polish(_Runner(worse), None, single, [single, pair], _Bar())
    assert kept is single and len(kept.samples) == 2  # a worse refit does not replace the fit


def test_the_refined_minimum_lies_between_the_evaluated_points():
    from drillgym.eval.diagnosis.intervals import refined_minimum

    optima = np.array([0.1031, 0.1029, 0.1033, 0.1027])  # all episodes agree on 0.103
    grid = np.linspace(0.0, 0.3, 31)  # evaluated every 0.01 only
    fit = refined_minimum(_samples(optima, grid))["latency"]["extra_latency_s"]
    assert fit == pytest.approx(0.103, abs=1e-6)  # the parabola through 0.09, 0.10, 0.11
    assert refined_minimum([]) == {}
    # Points evaluated twice (a fit and its refit share them) are counted once.
    samples = _samples(optima, grid)
    assert refined_minimum([*samples, *samples])["latency"]["extra_latency_s"] == pytest.approx(0.103, abs=1e-6)
