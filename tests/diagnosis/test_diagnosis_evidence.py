"""Starting points read off the data: where the drill first touches, and a registration read from it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from drillgym.envs.effects.registration import REFERENCE_BETA_RAD, Registration
from drillgym.eval.diagnosis.evidence import CONTACT_FORCE_N, contact_shift_m, first_contact


def _ramp(n: int, start: int, slope_n: float) -> np.ndarray:
    """Forces (n, 3): 0.01 N of noise-like ripple, then an axial ramp from sample ``start``."""
    f = np.zeros((n, 3))
    f[:, 0] = 0.01 * np.sin(np.arange(n))
    f[start:, 2] = slope_n * np.arange(1, n - start + 1)
    return f


def test_the_contact_shift_is_the_commanded_depth_between_the_two_first_touches():
    depth = np.arange(300) * 4e-6  # 0.4 mm/s at 100 Hz
    real, sim = _ramp(300, 150, 0.2), _ramp(300, 100, 0.2)
    assert first_contact(sim) == 100 + math.floor(CONTACT_FORCE_N / 0.2)
    assert contact_shift_m(real, sim, depth) == pytest.approx(50 * 4e-6)
    assert contact_shift_m(np.zeros((300, 3)), sim, depth) is None  # never touched: no reading


def test_a_registration_is_read_off_the_contact_shifts_of_holes_at_several_slopes():
    beta = np.radians([15.0, 20.0, 25.0, 30.0, 35.0, 20.0])
    dz, dx = 4e-4, 1e-3  # dz at the reference slope
    shift = dz + dx * (np.tan(beta) - math.tan(REFERENCE_BETA_RAD))
    guess = Registration.initial_guess({"contact_shift_m": shift, "beta_rad": beta})
    assert guess is not None
    assert guess["surface_dz_m"] == pytest.approx(dz, abs=1e-9)
    assert guess["entry_dx_m"] == pytest.approx(dx, abs=1e-9)
    assert guess["slope_error_rad"] == 0.0
    # one slope for all holes: the two displacements cannot be told apart, the axis offset takes it all
    same = Registration.initial_guess({"contact_shift_m": np.full(4, 5e-4), "beta_rad": np.full(4, 0.5)})
    assert same == {"surface_dz_m": pytest.approx(5e-4), "entry_dx_m": 0.0, "slope_error_rad": 0.0}
    assert Registration.initial_guess({"contact_shift_m": np.array([]), "beta_rad": np.array([])}) is None
