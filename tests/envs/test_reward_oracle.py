"""The reward terms and the action check against hand-computed values (:mod:`drillgym.envs.reward`).

The reward published in docs/training.md and the env's docstring is, per agent step,
``r = -w_dev · deviation_mm - w_force · lateral_force_n - w_smooth · |a - a_prev|² - w_peak · Δpeak_n``.
Every expected value below is worked out by hand in a comment from that formula, never with the module's
helpers. Floats are compared with ``pytest.approx`` at its default relative 1e-6: the hand values are exact
decimals and the code computes them in a handful of float operations (errors ~1e-16), so 1e-6 is only the
float slack, far below any change of a weight or a term (≥ 1 %).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from drillgym.envs.reward import RewardWeights, checked_action

PREV = np.array([0.0, 0.0, 0.0, 0.5])
ACTION = np.array([0.5, 0.0, 0.0, -0.5])  # |a - a_prev|² = 0.5² + 1.0² = 1.25


def test_default_weights_are_the_documented_ones():
    """The env's documented defaults (``DrillEnv``'s arguments; docs/training.md: the peak term off by default)."""
    w = RewardWeights()
    assert (w.deviation, w.force, w.smooth, w.peak_force) == (1.0, 0.1, 0.01, 0.0)


def test_each_term_is_minus_its_weight_times_its_quantity_in_the_documented_units():
    w = RewardWeights(deviation=2.0, force=0.5, smooth=0.1, peak_force=3.0)
    terms = w.terms(deviation_m=2.0e-4, lateral_force_n=1.5, action=ACTION, prev_action=PREV, peak_n=1.2)
    assert terms["deviation"] == pytest.approx(-2.0 * 0.2)  # 0.2 mm (the deviation comes in metres)
    assert terms["force"] == pytest.approx(-0.5 * 1.5)
    assert terms["smooth"] == pytest.approx(-0.1 * 1.25)
    assert terms["peak_force"] == pytest.approx(-3.0 * 0.3)  # the step raises the peak from 1.2 to 1.5 N
    assert set(terms) == {"deviation", "force", "smooth", "peak_force"}
    assert isinstance(terms["smooth"], float) and isinstance(terms["peak_force"], float)


def test_a_force_below_the_running_peak_costs_no_peak_term():
    w = RewardWeights(peak_force=3.0)
    below = w.terms(1e-4, 1.0, ACTION, PREV, peak_n=1.2)
    at = w.terms(1e-4, 1.2, ACTION, PREV, peak_n=1.2)
    assert below["peak_force"] == 0.0 and at["peak_force"] == 0.0


def test_the_peak_term_sums_to_minus_the_weight_times_the_episode_peak():
    """Forces 0.4, 1.0, 0.7, 1.3, 0.2 N from a peak of 0: the rises are 0.4, 0.6, 0, 0.3, 0 = 1.3 N, the peak."""
    w = RewardWeights(peak_force=2.0)
    peak, total = 0.0, 0.0
    for f in (0.4, 1.0, 0.7, 1.3, 0.2):
        total += w.terms(0.0, f, ACTION, ACTION, peak_n=peak)["peak_force"]
        peak = max(peak, f)
    assert total == pytest.approx(-2.0 * 1.3)


def test_an_unchanged_action_costs_no_smoothness():
    assert RewardWeights(smooth=5.0).terms(0.0, 0.0, ACTION, ACTION.copy(), 0.0)["smooth"] == 0.0


def test_a_batch_gives_one_term_per_episode_as_if_each_were_alone():
    """Episode 0 as above; episode 1 with zero change and a force 0.5 N below its peak of 2.0 N."""
    w = RewardWeights(deviation=2.0, force=0.5, smooth=0.1, peak_force=3.0)
    actions = np.stack([ACTION, np.zeros(4)])
    prev = np.stack([PREV, np.zeros(4)])
    terms = w.terms(np.array([2.0e-4, 1.0e-4]), np.array([1.5, 1.5]), actions, prev, np.array([1.2, 2.0]))
    np.testing.assert_allclose(terms["deviation"], [-0.4, -0.2])
    np.testing.assert_allclose(terms["force"], [-0.75, -0.75])
    np.testing.assert_allclose(terms["smooth"], [-0.125, 0.0])
    np.testing.assert_allclose(terms["peak_force"], [-0.9, 0.0])
    assert np.shape(terms["smooth"]) == (2,) and np.shape(terms["peak_force"]) == (2,)


@pytest.mark.parametrize("name", ["deviation", "force", "smooth", "peak_force"])
@pytest.mark.parametrize("bad", [-1e-9, -1.0, math.nan, math.inf, -math.inf, "1.0", None])
def test_a_negative_non_finite_or_non_number_weight_is_refused_naming_it(name, bad):
    with pytest.raises(ValueError, match=rf"^reward_{name}_weight={bad!r} must be a finite number >= 0$"):
        RewardWeights(**{name: bad})


@pytest.mark.parametrize("name", ["deviation", "force", "smooth", "peak_force"])
def test_a_zero_or_integer_weight_is_accepted_as_a_float(name):
    assert getattr(RewardWeights(**{name: 0.0}), name) == 0.0  # the bound itself is allowed
    w = RewardWeights(**{name: 2})
    assert getattr(w, name) == 2.0 and type(getattr(w, name)) is float


def test_an_action_is_clipped_to_plus_minus_one_and_returned_as_floats():
    out = checked_action([-2, 0.5, 1.5, -1], "env state unchanged")
    assert out.tolist() == [-1.0, 0.5, 1.0, -1.0] and out.dtype == np.float64
    inside = np.array([0.999, -0.999, 0.0, 1.0])
    assert checked_action(inside, "x").tolist() == inside.tolist()  # inside the range: unchanged
    single = checked_action(np.array([0.1, -0.2, 2.0, 0.0], dtype=np.float32), "x")  # an SB3 policy's float32
    assert single.dtype == np.float64 and single.tolist() == [float(np.float32(0.1)), float(np.float32(-0.2)), 1, 0]


@pytest.mark.parametrize("action", [np.zeros(3), np.zeros(5), np.zeros((1, 4))])
def test_an_action_of_the_wrong_shape_is_refused_with_both_shapes(action):
    with pytest.raises(ValueError, match=rf"^action must have shape \(4,\), got {re.escape(str(action.shape))}$"):
        checked_action(action, "env state unchanged")


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf, None])
def test_a_non_finite_action_is_refused_naming_the_consequence(bad):
    action = [0.0, bad, 0.0, 0.0]
    with pytest.raises(ValueError, match=r"contains NaN or inf; rejected \(nothing sent\)$"):
        checked_action(action, "nothing sent")


def test_a_batch_of_actions_is_checked_per_episode_and_names_the_bad_ones():
    ok = checked_action(np.array([[2.0, 0.0, 0.0, 0.0], [0.0, -3.0, 0.0, 0.5]]), "x", num_envs=2)
    assert ok.tolist() == [[1.0, 0.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.5]]
    with pytest.raises(ValueError, match=r"^action must have shape \(3, 4\), got \(2, 4\)$"):
        checked_action(np.zeros((2, 4)), "x", num_envs=3)
    bad = np.zeros((3, 4))
    bad[0, 2] = math.nan
    bad[2, 0] = math.inf
    with pytest.raises(
        ValueError, match=r"contains NaN or inf in episodes \[0, 2\]; rejected \(env state unchanged\)$"
    ):
        checked_action(bad, "env state unchanged", num_envs=3)


def test_the_compiled_batch_rewards_are_the_terms_and_their_sum_bit_for_bit():
    """``batch_rewards_into`` (the batched env's step and a batch's :meth:`RewardWeights.terms`) against numpy."""
    from drillgym.envs.reward import TERM_NAMES, batch_rewards_into

    rng = np.random.default_rng(0)
    w = RewardWeights(deviation=1.3, force=0.1, smooth=0.07, peak_force=2.5)
    n = 500
    dev, lateral, peak = rng.uniform(0, 1e-3, n), rng.uniform(0, 3, n), rng.uniform(0, 3, n)
    peak[:5] = lateral[:5]  # ties
    lateral[5] = math.nan
    action, prev = rng.uniform(-1, 1, (n, 4)), rng.uniform(-1, 1, (n, 4))
    running = rng.random(n) < 0.8
    change = np.add.reduce((action - prev) ** 2, axis=1)
    rise = np.maximum(lateral - peak, 0.0)
    want = {
        "deviation": -w.deviation * dev * 1e3,
        "force": -w.force * lateral,
        "smooth": -w.smooth * change,
        "peak_force": -w.peak_force * rise,
    }
    want_reward = np.where(running, want["deviation"] + want["force"] + want["smooth"] + want["peak_force"], 0.0)
    want_peak = np.maximum(peak, lateral)
    terms, reward, got_peak = np.empty((4, n)), np.empty(n), peak.copy()
    batch_rewards_into(w.vector(), dev, lateral, action, prev, got_peak, running, terms, reward)
    for k, name in enumerate(TERM_NAMES):
        assert np.array_equal(terms[k], want[name], equal_nan=True), name
    assert np.array_equal(reward, want_reward, equal_nan=True)
    assert np.array_equal(got_peak, want_peak, equal_nan=True)
