"""The F/T calibration error against its matrix written out by hand."""

from __future__ import annotations

import numpy as np

from drillgym.envs.effects.base import TraceView
from drillgym.envs.effects.sensor import FTGain


def test_a_calibration_error_reads_gains_on_each_axis_and_a_share_of_the_thrust_on_the_lateral_ones():
    force = np.array([[1.0, -2.0, 30.0], [0.0, 0.0, 0.0]])  # a drilling load (thrust 30 N), and no load
    torque = np.array([[0.1, 0.2, 0.3], [0.0, 0.0, 0.0]])
    view = TraceView(np.array([0.01, 0.02]), force.copy(), torque.copy(), np.ones(2), 0.15, 2e4)
    FTGain(fxy_gain=0.1, fz_gain=-0.2, fx_from_fz=0.02, fy_from_fz=-0.01).apply_to_trace(view)
    expected = [1.1 * 1.0 + 0.02 * 30.0, 1.1 * -2.0 - 0.01 * 30.0, 0.8 * 30.0]
    np.testing.assert_allclose(view.force_n[0], expected, rtol=0, atol=1e-12)
    assert np.all(view.force_n[1] == 0.0)  # nothing without load: a tared sensor reads zero
    assert np.array_equal(view.torque_nm, torque)  # the torque rows are separate
    wrench = np.concatenate([force, torque], axis=1)  # the simulated path reads the same
    np.testing.assert_allclose(
        FTGain(fxy_gain=0.1, fz_gain=-0.2, fx_from_fz=0.02, fy_from_fz=-0.01).sensor_wrenches(
            None, wrench, np.zeros(2)
        )[:, :3],
        view.force_n,
        atol=1e-12,
    )  # type: ignore[arg-type]
