"""Controller signs, scales and timing from synthetic observations: no simulator involved."""

import numpy as np
import pytest
from cell_plan import TCP_OFFSET_M
from cell_plan import plan_at_entry as _plan
from cell_plan import q_at_entry as _q_at_entry

from drillgym.controllers import Li2023Config, Li2023Controller, Zhang2005Controller, make_controller, parse_spec
from drillgym.controllers.models import RobotComplianceModel, tool_compliance_m_n
from drillgym.envs.cell_params import R_BASE_TASK
from drillgym.envs.constants import CONTROL_DT_S, MAX_CORRECTION_M, scale_action
from drillgym.envs.observation import OBS_BOUNDS


def _obs(force_sensor_n=(0.0, 0.0, 0.0), depth_m=2e-3, phase=1, tcp_error_base_m=(0.0, 0.0, 0.0), q=None):
    obs = {k: np.zeros(n, np.float32) for k, (n, _) in OBS_BOUNDS.items()}
    obs["ft_wrench_mean"][:3] = force_sensor_n
    obs["ft_wrench"][:3] = force_sensor_n
    obs["path_depth_m"][0] = depth_m
    obs["phase"][phase] = 1.0
    obs["tcp_error_base_m"][:] = tcp_error_base_m
    obs["q_rad"][:] = _q_at_entry() if q is None else q
    obs["feed_scale"][0] = 1.0
    return obs


def _correction_base_m(action) -> np.ndarray:
    return scale_action(np.asarray(action, dtype=float))[0]


def test_none_commands_zero_correction_and_nominal_feed():
    c = make_controller("none")
    c.set_plan(_plan())
    action, _ = c.predict(_obs((1.0, 2.0, -5.0)))
    assert np.all(action == 0.0)


def test_predict_needs_a_plan():
    with pytest.raises(RuntimeError, match="set_plan"):
        make_controller("li2023").predict(_obs())


def test_li2023_offline_correction_pushes_uphill_by_model_force_over_drill_stiffness():
    plan = _plan()
    c = Li2023Controller(Li2023Config(online=False))
    c.set_plan(plan)
    depths = np.linspace(0.0, 1.0e-3, 201)
    corr = np.array([c.offline_correction_base_m(d) for d in depths])
    task = corr @ R_BASE_TASK  # base -> task coordinates (R is orthonormal)
    i = int(np.argmax(np.linalg.norm(task, axis=1)))
    k_tool = 1.0 / tool_compliance_m_n(plan)[0, 0]
    assert task[i, 0] > 0  # the model pushes the drill downhill (-x), so the path moves uphill (+x)
    assert np.linalg.norm(task[i, :2]) == pytest.approx(c.config.model_peak_force_n / k_tool, rel=0.02)  # F / k_D
    assert np.allclose(task[:, 2], 0.0)  # never along the drill
    assert np.allclose(c.offline_correction_base_m(5e-3), 0.0)  # balanced once fully engaged


def test_li2023_online_correction_opposes_the_estimated_deviation_after_two_points():
    cfg = Li2023Config(offline=False, kp=4.0, ki=0.25)
    c = Li2023Controller(cfg)
    c.set_plan(_plan())
    force_task = np.array([-0.5, 0.0, -5.0])  # bone pushes the drill downhill (-x task)
    steps_per_point = round(cfg.point_period_s / CONTROL_DT_S)
    corrections = []
    for _ in range(4 * steps_per_point):
        corrections.append(_correction_base_m(c.predict(_obs(tuple(force_task)))[0]))
    corrections = np.array(corrections) @ R_BASE_TASK
    # nothing before the point computed at t=0 is applied at P_2 (1.2 s), reached by linear motion from P_1
    assert np.allclose(corrections[: steps_per_point - 1], 0.0, atol=1e-9)
    k_tool = 1.0 / tool_compliance_m_n(_plan())[0, 0]
    at_p2 = corrections[2 * steps_per_point - 1]
    expected = (cfg.kp + cfg.ki) * (0.5 / k_tool)  # tool part of the deviation; the arm adds ~1 %
    assert at_p2[0] == pytest.approx(expected, rel=0.05)
    assert abs(at_p2[2]) < 1e-9


def test_li2023_correction_is_clipped_to_the_action_range():
    c = Li2023Controller(Li2023Config(offline=False, kp=50.0))
    c.set_plan(_plan())
    for _ in range(40):
        action, _ = c.predict(_obs((-20.0, 0.0, 0.0)))
    assert np.max(np.abs(_correction_base_m(action))) <= MAX_CORRECTION_M + 1e-12


def test_li2023_y_gain_scales_only_the_correction_across_the_plane_of_inclination():
    force_task = (-0.4, -0.3, -5.0)  # downhill and across: both lateral axes get a correction
    runs = {}
    for y_gain in (1.0, 1.5):
        c = Li2023Controller(Li2023Config(y_gain=y_gain))
        c.set_plan(_plan())
        runs[y_gain] = np.array([_correction_base_m(c.predict(_obs(force_task))[0]) for _ in range(60)]) @ R_BASE_TASK
    assert np.abs(runs[1.0][:, 1]).max() > 1e-5  # y is corrected at all
    assert np.allclose(runs[1.5][:, 0], runs[1.0][:, 0], atol=1e-9)  # x unchanged (actions are float32)
    assert np.allclose(runs[1.5][:, 1], 1.5 * runs[1.0][:, 1], rtol=1e-5, atol=1e-9)  # y times the gain
    assert np.allclose(runs[1.5][:, 2], 0.0, atol=1e-9)  # never along the drill
    with pytest.raises(ValueError, match="y_gain"):
        Li2023Config(y_gain=float("nan"))


def test_li2023_rejects_a_filter_that_is_not_whole_agent_steps():
    with pytest.raises(ValueError, match="filter_samples"):
        Li2023Config(filter_samples=7)


def test_zhang2005_compensates_the_arm_deflection_of_the_measured_wrench():
    c = make_controller("zhang2005:cmrr=false,filter_samples=5")
    plan = _plan()
    c.set_plan(plan)
    force_task = np.array([0.0, 0.0, -10.0])  # pure thrust
    action, _ = c.predict(_obs(tuple(force_task)))
    q = _q_at_entry()
    model = RobotComplianceModel(TCP_OFFSET_M)
    j = model.jacobian(q)
    w = np.concatenate([R_BASE_TASK @ force_task, np.zeros(3)])
    expected = -(j[:3] @ model.joints.joint_deflection_rad(j, w))
    np.testing.assert_allclose(_correction_base_m(action), expected, rtol=1e-3, atol=1e-9)
    assert np.linalg.norm(expected) > 1e-5  # 10 N of thrust moves the arm by tens of microns


def test_zhang2005_feed_rises_below_the_thrust_reference_and_falls_above_it():
    def feed_after(thrust_n: float, steps: int = 20) -> float:
        c = Zhang2005Controller()
        c.set_plan(_plan(beta_deg=0.0))
        for _ in range(steps):
            action, _ = c.predict(_obs((0.0, 0.0, -thrust_n), depth_m=3e-3))
        return scale_action(np.asarray(action, dtype=float))[1]

    assert feed_after(2.0) > 1.5
    assert feed_after(14.0) < 0.7
    assert feed_after(100.0, 200) == pytest.approx(0.25)  # clamped at the slowest override
    assert feed_after(0.0, 200) == pytest.approx(4.0)  # and at the fastest


def test_zhang2005_keeps_nominal_feed_before_the_drill_is_fully_engaged():
    c = Zhang2005Controller()
    c.set_plan(_plan())
    for depth in (-1e-3, 0.2e-3):
        action, _ = c.predict(_obs((0.0, 0.0, -1.0), depth_m=depth))
        assert scale_action(np.asarray(action, dtype=float))[1] == pytest.approx(1.0)


def test_spec_overrides_are_typed_and_typos_are_errors():
    assert parse_spec("li2023:kp=1.0,ki=0.5") == ("li2023", {"kp": "1.0", "ki": "0.5"})
    c = make_controller("li2023:kp=1.0,offline=false")
    assert c.config.kp == 1.0 and c.config.offline is False
    with pytest.raises(ValueError, match="no parameter 'kpp'"):
        make_controller("li2023:kpp=1")
    with pytest.raises(ValueError, match="unknown controller"):
        make_controller("pid")
    with pytest.raises(ValueError, match="boolean"):
        make_controller("zhang2005:cmrr=maybe")


def test_describe_is_json_ready():
    import json

    d = make_controller("zhang2005").describe()
    assert d["name"] == "zhang2005"
    json.dumps(d)
