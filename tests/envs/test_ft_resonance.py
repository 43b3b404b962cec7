"""The F/T mode against the closed-form step response of a second-order system."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillgym.envs.effects.base import TraceView
from drillgym.envs.effects.resonance import FTResonance


@pytest.mark.parametrize(("freq_hz", "damping"), [(15.0, 0.05), (30.0, 0.3)])
def test_a_load_step_rings_as_a_second_order_mode_sampled_at_100_hz(freq_hz, damping):
    # Unit step at sample 0, held over the interval ending at it: y(t) = 1 − e^{−ζωt} (cos ω_d t + ζ/√(1−ζ²)
    # sin ω_d t) from t = −Δt, so sample k reads y((k + 1) Δt) (exact at the samples; no sample's delay).
    n = 60
    force = np.zeros((n, 3))
    force[:, 2] = 1.0
    view = TraceView(np.arange(n) * 0.01, force, np.zeros((n, 3)), np.ones(n), 0.15, 20000.0)
    FTResonance(amplitude=1.0, freq_lateral_hz=45.0, freq_axial_hz=freq_hz, damping=damping).apply_to_trace(view)
    w = 2.0 * math.pi * freq_hz
    wd = w * math.sqrt(1.0 - damping**2)
    t = (np.arange(n) + 1) * 0.01
    expected = 1.0 - np.exp(-damping * w * t) * (
        np.cos(wd * t) + damping / math.sqrt(1.0 - damping**2) * np.sin(wd * t)
    )
    np.testing.assert_allclose(view.force_n[:, 2], expected, atol=1e-12)
    assert np.all(view.force_n[:, :2] == 0.0)


def test_half_the_reading_through_the_mode_rings_half_as_much_and_a_steady_load_reads_true():
    n = 400
    force = np.ones((n, 3))
    full, half = (TraceView(np.arange(n) * 0.01, force.copy(), force.copy(), np.ones(n), 0.15, 2e4) for _ in range(2))
    FTResonance(amplitude=1.0, freq_lateral_hz=20.0, freq_axial_hz=20.0, damping=0.1).apply_to_trace(full)
    FTResonance(amplitude=0.5, freq_lateral_hz=20.0, freq_axial_hz=20.0, damping=0.1).apply_to_trace(half)
    np.testing.assert_allclose(half.force_n - 1.0, 0.5 * (full.force_n - 1.0), atol=1e-12)
    assert abs(full.force_n[-1, 0] - 1.0) < 1e-9 and abs(full.torque_nm[-1, 2] - 1.0) < 1e-9


def test_each_mode_starts_where_its_own_axes_ring_most_or_where_all_do():
    peaks = {"all": 25.0, "lateral": 15.0, "axial": 30.0}
    guess = FTResonance.initial_guess({"excess_peaks_hz": peaks})
    assert guess is not None and (guess["freq_lateral_hz"], guess["freq_axial_hz"]) == (15.0, 30.0)
    guess = FTResonance.initial_guess({"excess_peaks_hz": {"all": 60.0, "lateral": None, "axial": 2.0}})
    assert guess is not None and (guess["freq_lateral_hz"], guess["freq_axial_hz"]) == (45.0, 5.0)  # kept in range
    assert FTResonance.initial_guess({"excess_peaks_hz": {"all": None}}) is None  # no ringing: no reading
