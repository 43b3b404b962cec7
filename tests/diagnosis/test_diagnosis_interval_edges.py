"""Parameter intervals at their edges (intervals.py): the search's bounds, the off point, the refinement between
evaluated points, points with more terms, degenerate fits. Evaluated points and their misfits are built by hand.

A misfit quadratic in the parameter puts the parabola's vertex exactly at its optimum, so a refined fit is compared
to 1e-9 (rounding of O(0.1) values over steps of 0.01 is ~1e-15; a fit that snapped to a point would be off by
≥ 0.003 here). Misfits of a few hand-picked values are compared exactly where the result is one of them.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from drillgym.eval.diagnosis.context import make_spec
from drillgym.eval.diagnosis.intervals import expanded_tail, off_point_inside, parameter_intervals, refined_minimum

T_1_975 = 12.7062
"""Student's t, 1 degree of freedom, 97.5 % (tables)."""


def test_the_expanded_tail_of_two_episodes_is_a_t_interval_on_one_degree_of_freedom():
    """Φ(−√(2/1) · t₁) = ½ erfc(t₁): about 1.7e-72 (to 1e-3 relative: the table's 6 digits of t)."""
    assert expanded_tail(2) == pytest.approx(0.5 * math.erfc(T_1_975), rel=1e-3)


@pytest.mark.parametrize(("n", "level", "tail"), [(1, 0.95, 0.025), (0, 0.95, 0.025), (1, 0.9, 0.05)])
def test_with_fewer_than_two_episodes_the_tail_is_the_plain_percentile(n, level, tail):
    assert expanded_tail(n, level) == pytest.approx(tail, rel=1e-12)


def _latency(values, misfit, n=None, episodes: int = 4):
    """Evaluated latencies (s); each episode's J = ``misfit(x)`` over ``n(x)`` terms (10 unless given)."""
    out = []
    for x in values:
        terms = 10.0 if n is None else n(x)
        out.append(
            (
                make_spec(("latency",), [{"extra_latency_s": float(x)}]),
                np.full(episodes, misfit(x) * terms),
                np.full(episodes, terms),
            )
        )
    return out


def _bowl(x: float, optimum: float = 0.103) -> float:
    return 1.0 + 1e3 * (x - optimum) ** 2


GRID = np.linspace(0.0, 0.3, 31)


def test_an_interval_at_the_off_point_contains_it_and_reaches_the_search_edge():
    """Every episode at no latency: the fit is 0 in every resample, the lowest value the search tried."""
    ci = parameter_intervals(_latency(GRID, lambda x: _bowl(x, 0.0)))["latency"]["extra_latency_s"]
    assert ci == {"low": 0.0, "high": 0.0, "contains_off": True, "at_search_edge": True}


def test_an_interval_at_the_top_of_the_search_reaches_its_edge_and_does_not_contain_the_off_point():
    ci = parameter_intervals(_latency(GRID, lambda x: _bowl(x, 0.3)))["latency"]["extra_latency_s"]
    assert ci == {"low": 0.3, "high": 0.3, "contains_off": False, "at_search_edge": True}


def test_a_fit_is_the_lowest_mean_term_not_the_lowest_sum_when_points_have_different_numbers_of_terms():
    """Mean terms 1.0, 0.6 and 0.9 at 0, 0.1 and 0.2 s, the middle one over twice the terms (sums 10, 12, 9):
    the parabola through the means has its vertex at 7.5 / 70 = 3/28 s."""
    means, terms = {0.0: 1.0, 0.1: 0.6, 0.2: 0.9}, {0.0: 10.0, 0.1: 20.0, 0.2: 10.0}
    samples = _latency(means, lambda x: means[x], n=lambda x: terms[x])
    assert refined_minimum(samples)["latency"]["extra_latency_s"] == pytest.approx(3 / 28, abs=1e-9)
    ci = parameter_intervals(samples)["latency"]["extra_latency_s"]  # identical episodes: every resample the same
    assert ci["low"] == pytest.approx(3 / 28, abs=1e-9) and ci["high"] == pytest.approx(3 / 28, abs=1e-9)


@pytest.mark.parametrize("order", [(0.09, 0.10, 0.11), (0.11, 0.09, 0.10), (0.10, 0.11, 0.09)])
def test_the_fit_is_refined_between_the_evaluated_points_in_whatever_order_they_were_evaluated(order):
    assert refined_minimum(_latency(order, _bowl))["latency"]["extra_latency_s"] == pytest.approx(0.103, abs=1e-9)


def test_a_parameter_that_changes_nothing_stays_at_the_best_point_without_a_warning():
    """A flat misfit: no parabola (0 / 0), so the best point evaluated first (0.1 s) stands."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit = refined_minimum(_latency((0.10, 0.09, 0.11), lambda x: 1.0))
    assert fit == {"latency": {"extra_latency_s": 0.10}}


def _drift(points, misfit, episodes: int = 4):
    """A pair with the latency held at 0.1 s and the F/T drift's fx and fy rates (N/s) evaluated at ``points``."""
    out = []
    for fx, fy in points:
        spec = make_spec(("latency", "ft_drift"), [{"extra_latency_s": 0.1}, {"fx_rate_n_s": fx, "fy_rate_n_s": fy}])
        out.append((spec, np.full(episodes, 10.0 * misfit(fx, fy)), np.full(episodes, 10.0)))
    return out


def test_a_held_parameter_is_not_refined_and_the_free_ones_are_along_their_own_lines():
    """A bowl at fx = 0.013, fy = −0.027 evaluated every 0.01 on a 5 × 5 grid, listed shuffled: each rate is refined
    along the points that share the other's value, to its optimum; the held latency stays 0.1."""
    grid = [(fx, fy) for fx in (-0.01, 0.0, 0.01, 0.02, 0.03) for fy in (-0.05, -0.04, -0.03, -0.02, -0.01)]
    shuffled = [grid[i] for i in np.random.default_rng(0).permutation(len(grid))]
    fit = refined_minimum(_drift(shuffled, lambda fx, fy: 1.0 + 1e3 * ((fx - 0.013) ** 2 + 2.0 * (fy + 0.027) ** 2)))
    assert fit["latency"] == {"extra_latency_s": 0.1}
    assert fit["ft_drift"]["fx_rate_n_s"] == pytest.approx(0.013, abs=1e-9)
    assert fit["ft_drift"]["fy_rate_n_s"] == pytest.approx(-0.027, abs=1e-9)
    intervals = parameter_intervals(_drift(shuffled, lambda fx, fy: 1.0 + (fx - 0.013) ** 2 + (fy + 0.027) ** 2))
    assert intervals["latency"] == {"extra_latency_s": None}


def test_a_fit_with_one_evaluated_point_has_no_interval_and_that_point_as_its_minimum():
    samples = _latency([0.05], _bowl)
    assert parameter_intervals(samples) == {"latency": {"extra_latency_s": None}}
    assert refined_minimum(samples) == {"latency": {"extra_latency_s": 0.05}}


def test_points_without_every_episodes_terms_are_left_out():
    good = _latency((0.09, 0.10, 0.11), _bowl)
    spec = make_spec(("latency",), [{"extra_latency_s": 0.2}])
    broken = [(spec, np.full(4, 1.0), None), (spec, None, np.full(4, 10.0)), (spec, np.array([1.0, np.nan]), None)]
    assert refined_minimum([*good, *broken]) == refined_minimum(good)


def test_the_intervals_are_reproducible_from_their_seed_zero_by_default():
    optima = 0.1 + 0.02 * np.random.default_rng(3).standard_normal(8)
    n = np.full(8, 10.0)
    samples = [
        (make_spec(("latency",), [{"extra_latency_s": float(x)}]), 10.0 * ((x - optima) ** 2 + 1.0), n) for x in GRID
    ]
    by_seed = {s: parameter_intervals(samples, s)["latency"]["extra_latency_s"] for s in (0, 1)}
    assert by_seed[0] != by_seed[1]
    assert parameter_intervals(samples)["latency"]["extra_latency_s"] == by_seed[0]


def test_an_effect_without_intervals_is_not_judged_by_the_off_point_rule():
    intervals = {"latency": {"extra_latency_s": {"low": 0.0, "high": 0.1, "contains_off": True}}}
    assert off_point_inside(intervals, ["ft_drift", "latency"]) == ["latency"]
