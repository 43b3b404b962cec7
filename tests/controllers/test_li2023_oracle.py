"""``li2023`` against hand-worked timelines of Li 2023's equations (§2.3, eq. 14-15, Fig. 7), no simulator.

With no force on the sensor the controller's deviation estimate is the executed correction it reads from
RTDE (``tcp_error_base_m``) projected across the drill, so a test that feeds a known ``tcp_error`` knows the
deviation Δx_i at every path point i exactly. From there, by hand: ``Δd_i = Δx_i − Δx_{i−1}``,
``u_i = KP Δd_i + KI Σ Δd + KD (Δd_i − Δd_{i−1})``, the correction −u_i reached at point i + 2 (path prediction)
by linear motion from the previous corrected point, one point (0.6 s = 12 agent steps of 0.05 s) earlier.

Tolerance: actions are float32 in [−1, 1] for ±2 mm, so a correction read back from an action is within
2 mm · 2⁻²⁴ ≈ 1.2e-10 m of its float64 value; the tests allow 1e-9 m (a change of any gain, time or sign in
these timelines moves a correction by ≥ 1e-6 m).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from cell_plan import plan_at_entry as _plan
from cell_plan import q_at_entry as _q_at_entry

from drillgym.controllers import Li2023Config, Li2023Controller
from drillgym.controllers.models import OfflineForceModel, RobotComplianceModel
from drillgym.envs.cell_params import R_BASE_TASK
from drillgym.envs.constants import CONTROL_DT_S, SUBSTEPS_PER_STEP, scale_action
from drillgym.envs.observation import OBS_BOUNDS

STEPS_PER_POINT = 12  # 0.6 s / 0.05 s
ATOL_M = 1e-9
X_TASK, Y_TASK, Z_TASK = R_BASE_TASK[:, 0], R_BASE_TASK[:, 1], R_BASE_TASK[:, 2]
LATERAL = np.outer(X_TASK, X_TASK) + np.outer(Y_TASK, Y_TASK)  # projector across the drill (base frame)


Q_ENTRY = _q_at_entry()


def _obs(tcp_error_base_m=(0.0, 0.0, 0.0), force_sensor_n=(0.0, 0.0, 0.0), depth_m=0.15e-3):
    """An observation on the paper plan; the default depth is in the entry, where the offline profile is ~0.6 mm
    (so a test with ``offline=False`` also checks that it is off)."""
    obs = {k: np.zeros(n, np.float32) for k, (n, _) in OBS_BOUNDS.items()}
    obs["ft_wrench_mean"][:3] = force_sensor_n
    obs["path_depth_m"][0] = depth_m
    obs["phase"][1] = 1.0
    obs["tcp_error_base_m"][:] = tcp_error_base_m
    obs["q_rad"][:] = Q_ENTRY
    obs["feed_scale"][0] = 1.0
    return obs


def _controller(**config) -> Li2023Controller:
    c = Li2023Controller(Li2023Config(**config))
    c.set_plan(_plan())
    return c


def _run(c: Li2023Controller, obs_of_step, steps: int) -> np.ndarray:
    """Corrections (m, base frame) commanded at steps 0..steps-1; ``obs_of_step(k)`` is step k's observation."""
    out = []
    for k in range(steps):
        action = c.act(obs_of_step(k))
        assert action.dtype == np.float32 and action[3] == 0.0  # nominal feed: li2023 never changes it
        out.append(scale_action(np.asarray(action, dtype=float))[0])
    return np.array(out)


def _expected(points_t: list[float], points_c: list[np.ndarray], steps: int) -> np.ndarray:
    """Linear motion through the corrected points (time s, correction m), held before the first and after the last;
    step k commands where the robot will be at the end of the step, (k + 1) · 0.05 s."""
    t = (np.arange(steps) + 1) * CONTROL_DT_S
    c = np.array(points_c)
    return np.stack([np.interp(t, points_t, c[:, j]) for j in range(3)], axis=1)


def _deviation(tcp_error: np.ndarray) -> np.ndarray:
    """Δx as the controller reads it: the float32 observation projected across the drill (float64)."""
    return LATERAL @ np.asarray(tcp_error, dtype=np.float32).astype(float)


# --------------------------------------------------------------------------------------------- online PID


@pytest.mark.parametrize("prediction_points", [2, 1, 3])
def test_the_online_correction_follows_eq_14_15_with_path_prediction_and_a_20_sample_filter(prediction_points):
    """KP 4, KI 0.25, KD 0.4; executed correction D = 61 µm along task x for steps 0-8, 3D from step 9 on.

    Points are computed at steps 0, 12, 24, 36 from the 4-step filter (20 F/T samples): Δx = D (step 0 alone),
    then 3D (steps 9-12, 21-24, ...), so Δd = D, 2D, 0, 0 and by hand
    u0 = (4 + 0.25 + 0.4) D = 4.65 D; u1 = 4·2D + 0.25·3D + 0.4·(2D − D) = 9.15 D; u2 = 0.25·3D + 0.4·(0 − 2D) = −0.05 D;
    u3 = 0.25·3D = 0.75 D. Point i (correction −u_i) is reached at (i + p) · 0.6 s, moving from the previous one
    from one period earlier; before the first, nothing.
    """
    d_vec = 2.0**-14 * X_TASK

    def obs(k: int):
        return _obs(tcp_error_base_m=(d_vec if k < 9 else 3.0 * d_vec))

    c = _controller(offline=False, kp=4.0, ki=0.25, kd=0.4, prediction_points=prediction_points)
    got = _run(c, obs, 60)
    d = _deviation(d_vec)
    u = [4.65 * d, 9.15 * d, -0.05 * d, 0.75 * d]
    p = prediction_points
    times = [0.6 * (p - 1)] + [0.6 * (i + p) for i in range(4)]
    want = _expected(times, [np.zeros(3)] + [-ui for ui in u], 60)
    np.testing.assert_allclose(got, want, rtol=0.0, atol=ATOL_M)
    assert np.abs(got @ Z_TASK).max() < ATOL_M  # never along the drill


def test_the_filter_averages_the_last_filter_samples_of_the_executed_correction():
    """filter_samples 20 = 4 agent steps: executed correction 0 for steps 0-9, then 4D (D = 61 µm, task y).
    Point 1 (step 12) averages steps 9-12: (0 + 4D + 4D + 4D) / 4 = 3D, so with KP 0, KI 1, KD 0: u1 = 3D reached
    at 1.8 s, u0 = 0 at 1.2 s; a 5-sample filter (one step) sees 4D, a 40-sample one (8 steps) 1.5D."""
    d_vec = 2.0**-14 * Y_TASK

    def obs(k: int):
        return _obs(tcp_error_base_m=(np.zeros(3) if k < 10 else 4.0 * d_vec))

    for filter_samples, seen in ((20, 3.0), (5, 4.0), (40, 1.5)):  # 40 samples: steps 5-12, 3 of 8 at 4D
        c = _controller(offline=False, kp=0.0, ki=1.0, kd=0.0, filter_samples=filter_samples)
        got = _run(c, obs, 36)
        seen_d = _deviation(seen * d_vec)
        want = _expected([0.6, 1.2, 1.8], [np.zeros(3), np.zeros(3), -seen_d], 36)
        np.testing.assert_allclose(got, want, rtol=0.0, atol=ATOL_M, err_msg=f"filter_samples={filter_samples}")


def test_the_filter_averages_the_last_filter_samples_of_the_force_too():
    """As above with the sensor force instead: 0 for steps 0-9, then F = (−0.5, 0.3, −5) N; point 1 averages
    steps 9-12, 3/4 F, and the deviation is linear in the force: Δx1 = Δx(3F/4) (next section's oracle)."""
    force = np.array([-0.5, 0.3, -5.0], dtype=np.float32).astype(float)

    def obs(k: int):
        return _obs(force_sensor_n=(np.zeros(3) if k < 10 else force))

    for filter_samples, seen in ((20, 0.75), (5, 1.0)):
        c = _controller(offline=False, kp=0.0, ki=1.0, kd=0.0, filter_samples=filter_samples)
        got = _run(c, obs, 36)
        want = _expected([0.6, 1.2, 1.8], [np.zeros(3), np.zeros(3), -_deviation_of_force(seen * force)], 36)
        np.testing.assert_allclose(got, want, rtol=0.0, atol=ATOL_M, err_msg=f"filter_samples={filter_samples}")


def test_each_corrected_point_is_clipped_before_the_robot_moves_between_them():
    """KP 4 only; D = 0.61 mm along x for steps 0-8, then 0: u0 = 4D, u1 = 4 (0 − D) = −4D, both beyond the 0.5 mm
    limit, so the points are −0.5 mm at 1.2 s and +0.5 mm at 1.8 s and the robot moves linearly between them
    (a clip of the interpolated total instead would stay at −0.5 mm until 1.5 s)."""
    d_vec = 2.0**-14 * 10.0 * X_TASK
    limit = 0.5e-3

    def obs(k: int):
        return _obs(tcp_error_base_m=(d_vec if k < 9 else np.zeros(3)))

    c = _controller(offline=False, kp=4.0, ki=0.0, kd=0.0, max_correction_m=limit)
    got = _run(c, obs, 36)
    u0 = 4.0 * _deviation(d_vec)
    clipped = np.clip(-u0, -limit, limit)
    want = _expected([0.6, 1.2, 1.8], [np.zeros(3), clipped, -clipped], 36)
    np.testing.assert_allclose(got, want, rtol=0.0, atol=ATOL_M)
    assert np.abs(got).max() <= limit + ATOL_M


def test_the_total_correction_is_clipped_per_base_axis_to_the_configured_limit():
    """A large deviation (KP 50): every commanded base-axis correction stays within ±0.3 mm and reaches it."""
    c = _controller(offline=False, kp=50.0, max_correction_m=0.3e-3)
    got = _run(c, lambda k: _obs(tcp_error_base_m=2.0**-12 * X_TASK), 48)
    assert np.abs(got).max() == pytest.approx(0.3e-3, abs=ATOL_M)


def test_without_the_executed_correction_the_deviation_is_the_deflection_alone():
    """``count_executed_correction=False`` is Li's eq. 13 literally: the RTDE correction is not part of Δx, so with
    no force there is nothing to correct."""
    c = _controller(offline=False, count_executed_correction=False)
    got = _run(c, lambda k: _obs(tcp_error_base_m=2.0**-14 * X_TASK), 36)
    np.testing.assert_allclose(got, 0.0, atol=ATOL_M)


def test_no_online_correction_when_online_is_off():
    c = _controller(offline=False, online=False)
    got = _run(c, lambda k: _obs(tcp_error_base_m=2.0**-14 * X_TASK), 36)
    np.testing.assert_allclose(got, 0.0, atol=ATOL_M)


def test_x_only_compensation_leaves_the_deviation_across_the_plane_of_inclination_alone():
    """axes="x" (Li's main direction only): a deviation along task y is not corrected, one along x is."""
    for axis, corrected in ((Y_TASK, False), (X_TASK, True)):
        c = _controller(offline=False, axes="x", kp=4.0, ki=0.25)
        got = _run(c, lambda k, a=axis: _obs(tcp_error_base_m=2.0**-14 * a), 24)
        assert bool(np.abs(got[-1]).max() > 1e-6) == corrected
        np.testing.assert_allclose(got @ Y_TASK, 0.0, atol=ATOL_M)
        np.testing.assert_allclose(got @ Z_TASK, 0.0, atol=ATOL_M)


def test_axes_other_than_x_or_xy_are_refused_when_the_plan_is_set():
    with pytest.raises(ValueError, match=r"^axes='y' must be 'x' or 'xy'$"):
        Li2023Controller(Li2023Config(axes="y")).set_plan(_plan())


# --------------------------------------------------------------------------------------------- deviation estimate


def _k_lat(stickout_m: float, ratio: float = 0.85, diameter_m: float = 1.5e-3) -> float:
    """3EI/l³ of the drill, E = 210 GPa, I = π (ratio · D)⁴ / 64 (docs/physics.md §2)."""
    return 3.0 * 210e9 * math.pi * (ratio * diameter_m) ** 4 / 64.0 / stickout_m**3


def _k_ax(stickout_m: float, ratio: float = 0.85, diameter_m: float = 1.5e-3) -> float:
    return 210e9 * math.pi * (ratio * diameter_m) ** 2 / 4.0 / stickout_m


def _deviation_of_force(force_sensor_n: np.ndarray, ratio: float = 0.85) -> np.ndarray:
    """Δx of a sensor force with no executed correction: P (C_D R F + R K_FD⁻¹ F) at the entry pose."""
    plan = _plan()
    arm = RobotComplianceModel(plan.tcp_offset_m).translational_compliance_m_n(Q_ENTRY) @ (R_BASE_TASK @ force_sensor_n)
    k_lat, k_ax = _k_lat(plan.stickout_m, ratio), _k_ax(plan.stickout_m, ratio)
    return LATERAL @ (arm + R_BASE_TASK @ (force_sensor_n / np.array([k_lat, k_lat, k_ax])))


@pytest.mark.parametrize("ratio", [0.85, 0.7])
def test_the_deviation_estimate_is_executed_correction_plus_arm_and_drill_deflection_across_the_drill(ratio):
    """Δx = P (e + C_D R F + R K_FD⁻¹ F) (Li eq. 13 plus the executed correction): P the projector across the
    drill, R the task-to-base rotation (the sensor's axes are the task's at the nominal pose), C_D the arm's
    compliance (the controller's arm model, :class:`RobotComplianceModel`, tested on its own), K_FD⁻¹ the
    drill's diag(1/k_lat, 1/k_lat, 1/k_ax) by hand with the configured bending-diameter ratio. Relative 1e-9:
    float slack."""
    plan = _plan()
    c = Li2023Controller(Li2023Config(tool_effective_diameter_ratio=ratio))
    c.set_plan(plan)
    force = np.array([-0.5, 0.3, -5.0])  # sensor (task) frame, N
    executed = np.array([1e-5, -2e-5, 3e-5])
    got = c.deviation_estimate_base_m(Q_ENTRY, executed, force)
    np.testing.assert_allclose(got, LATERAL @ executed + _deviation_of_force(force, ratio), rtol=1e-9, atol=1e-15)
    assert abs(got @ Z_TASK) < 1e-15


# --------------------------------------------------------------------------------------------- offline path


@pytest.mark.parametrize("peak_n", [1.2, 2.4])
def test_the_offline_correction_is_minus_the_model_force_over_the_drill_stiffness_at_the_observed_depth(peak_n):
    """ΔP = −k_D⁻¹ F_model(d) at the observation's path depth d (Fig. 6, upper path): F_model from the
    controller's force model scaled to ``model_peak_force_n`` (:class:`OfflineForceModel`, tested on its own),
    k_D the drill's 3EI/l³ by hand. The offline part is in place from the first step (no filter, no PID)."""
    plan = _plan()
    model = OfflineForceModel.for_plan(plan, peak_n)
    c = _controller(online=False, model_peak_force_n=peak_n)
    depths = [0.0, 0.05e-3, 0.15e-3, 0.3e-3, 0.6e-3, 3e-3]
    got = _run(c, lambda k: _obs(depth_m=depths[k]), len(depths))
    k_lat = _k_lat(plan.stickout_m)
    for g, d in zip(got, depths, strict=True):
        fx, fy = model.lateral_at(float(np.float32(d)))
        np.testing.assert_allclose(g, -(fx * X_TASK + fy * Y_TASK) / k_lat, rtol=0.0, atol=ATOL_M)
    assert np.abs(got[2]).max() > 1e-5  # the peak region is corrected at all


@pytest.mark.parametrize("beta_deg", [30.0, -30.0])
def test_the_total_correction_is_clipped_per_base_axis_on_both_sides(beta_deg):
    """The offline profile alone (~0.6 mm in the entry, uphill: +task x at β 30°, −x at −30°) against a limit of
    0.1 mm: every base axis is clipped to ±0.1 mm, on the side the profile pushes."""
    plan = _plan(beta_deg=beta_deg)
    model = OfflineForceModel.for_plan(plan)
    c = Li2023Controller(Li2023Config(online=False, max_correction_m=0.1e-3))
    c.set_plan(plan)
    got = _run(c, lambda k: _obs(depth_m=0.15e-3), 1)[0]
    fx, fy = model.lateral_at(float(np.float32(0.15e-3)))
    unclipped = -(fx * X_TASK + fy * Y_TASK) / _k_lat(plan.stickout_m)
    assert np.abs(unclipped).max() > 0.2e-3
    np.testing.assert_allclose(got, np.clip(unclipped, -0.1e-3, 0.1e-3), rtol=0.0, atol=ATOL_M)
    assert np.sign(got @ X_TASK) == np.sign(beta_deg)  # the path moves uphill, against the downhill force
    assert abs(got @ X_TASK) == pytest.approx(0.1e-3, abs=ATOL_M)


def test_y_gain_scales_the_whole_correction_across_the_plane_of_inclination_only():
    """Offline and online together (KP 4, a deviation along x and y): with y_gain g (1.4, 2, 0) the task-y part is
    g times that of y_gain 1, task x unchanged, nothing along the drill."""
    dev = 2.0**-14 * (X_TASK + Y_TASK)
    runs = {}
    for g in (1.0, 1.4, 2.0, 0.0):
        c = _controller(y_gain=g)
        runs[g] = _run(c, lambda k: _obs(tcp_error_base_m=dev, depth_m=0.1e-3 + 1e-5 * k), 36)
    for g in (1.4, 2.0, 0.0):
        np.testing.assert_allclose(runs[g] @ X_TASK, runs[1.0] @ X_TASK, atol=ATOL_M)
        np.testing.assert_allclose(runs[g] @ Y_TASK, g * (runs[1.0] @ Y_TASK), atol=2 * ATOL_M)
        np.testing.assert_allclose(runs[g] @ Z_TASK, 0.0, atol=ATOL_M)
    assert np.abs(runs[1.0] @ Y_TASK).max() > 1e-6


# --------------------------------------------------------------------------------------------- episodes


def test_a_new_plan_or_reset_starts_from_an_empty_filter_pid_and_queue():
    """A controller that ran 30 steps on a large deviation and then gets a plan again commands exactly what a
    fresh one does (the filter, the PID memory, the queued points and the step counter all start over)."""
    busy = _controller(kp=4.0, ki=0.25, kd=0.4)
    _run(busy, lambda k: _obs(tcp_error_base_m=2.0**-12 * (X_TASK - Y_TASK), depth_m=1e-4), 30)
    busy.set_plan(_plan())

    def obs(k: int):
        return _obs(tcp_error_base_m=2.0**-14 * (k % 7) * X_TASK, depth_m=1e-5 * k)

    np.testing.assert_array_equal(_run(busy, obs, 40), _run(_controller(kp=4.0, ki=0.25, kd=0.4), obs, 40))
    busy.reset()
    np.testing.assert_array_equal(_run(busy, obs, 40), _run(_controller(kp=4.0, ki=0.25, kd=0.4), obs, 40))


# --------------------------------------------------------------------------------------------- configuration


def test_the_default_configuration_is_the_papers_best_setting():
    """Li §4: KP 4 best, 20 samples at 100 Hz, 600 ms per point, prediction two points ahead."""
    cfg = Li2023Config()
    assert (cfg.kp, cfg.ki, cfg.kd) == (4.0, 0.25, 0.0)
    assert (cfg.filter_samples, cfg.point_period_s, cfg.prediction_points) == (20, 0.6, 2)
    assert cfg.offline and cfg.online and cfg.count_executed_correction
    assert (cfg.axes, cfg.y_gain, cfg.max_correction_m, cfg.tool_effective_diameter_ratio) == ("xy", 1.0, 2e-3, 0.85)
    assert Li2023Controller().steps_per_point == STEPS_PER_POINT


@pytest.mark.parametrize("ok", [SUBSTEPS_PER_STEP, 2 * SUBSTEPS_PER_STEP, 20])
def test_a_filter_of_whole_agent_steps_is_accepted(ok):
    assert Li2023Config(filter_samples=ok).filter_samples == ok


@pytest.mark.parametrize("bad", [0, -SUBSTEPS_PER_STEP, 1, SUBSTEPS_PER_STEP - 1, SUBSTEPS_PER_STEP + 1, 21])
def test_a_filter_that_is_not_a_positive_whole_number_of_agent_steps_is_refused(bad):
    message = rf"^filter_samples={bad} must be a positive multiple of 5 \(F/T samples per agent step\)$"
    with pytest.raises(ValueError, match=message):
        Li2023Config(filter_samples=bad)


@pytest.mark.parametrize(("period", "steps"), [(CONTROL_DT_S, 1), (0.6, 12), (1.2, 24), (0.6 + 1e-12, 12)])
def test_a_point_period_of_whole_agent_steps_is_accepted(period, steps):
    """1e-12 s off a whole number of steps is float rounding (the check allows 1e-9 steps, 5e-11 s)."""
    assert Li2023Controller(Li2023Config(point_period_s=period)).steps_per_point == steps


@pytest.mark.parametrize("bad", [0.0, -0.6, 0.61, 0.025, 0.6 + 1e-9, 1e-12, 5e-11, math.nan, math.inf, -math.inf])
def test_a_point_period_that_is_not_a_positive_whole_number_of_agent_steps_is_refused(bad):
    """0.6 + 1e-9 s is 2e-8 steps off: above the 1e-9-step rounding allowance. 1e-12 s and 5e-11 s are within
    1e-9 steps of 0 steps: no step per point at all."""
    with pytest.raises(ValueError, match=rf"^point_period_s={bad} must be a positive multiple of 0.05 s$"):
        Li2023Config(point_period_s=bad)


def test_prediction_must_look_at_least_one_point_ahead():
    assert Li2023Config(prediction_points=1).prediction_points == 1
    for bad in (0, -1):
        with pytest.raises(ValueError, match=rf"^prediction_points={bad} must be >= 1$"):
            Li2023Config(prediction_points=bad)


@pytest.mark.parametrize("gain", ["kp", "ki", "kd"])
@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_gain_is_refused(gain, bad):
    with pytest.raises(ValueError, match=r"^kp, ki and kd must be finite$"):
        Li2023Config(**{gain: bad})


@pytest.mark.parametrize("ok", [0.0, 1.0, 3.0])
def test_a_y_gain_from_0_to_3_is_accepted(ok):
    assert Li2023Config(y_gain=ok).y_gain == ok


@pytest.mark.parametrize("bad", [-1e-9, 3.0 + 1e-9, math.nan, math.inf, -math.inf])
def test_a_y_gain_outside_0_to_3_is_refused(bad):
    with pytest.raises(ValueError, match=rf"^y_gain={bad} must lie in \[0, 3\]$"):
        Li2023Config(y_gain=bad)
