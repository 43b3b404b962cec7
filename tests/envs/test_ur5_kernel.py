"""The compiled UR5 kinematics (envs/robot/ur5_kernel.py) against Pinocchio and numpy, to rounding."""

import numpy as np
import pinocchio as pin
import pytest

from drillgym.envs.robot import ur5_kernel as kernel
from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD, JointCompliance
from drillgym.envs.robot.ur5 import Q_HOME_RAD, TCP_FRAME, TRACKER_FRAME, UR5Kinematics

KIN = UR5Kinematics(0.28, (0.05, 0.01, 0.06))
ANGLES = np.random.default_rng(0).uniform(-np.pi, np.pi, (50, 6))


@pytest.mark.parametrize("frame", [TCP_FRAME, TRACKER_FRAME])
def test_frame_pose_and_jacobian_equal_pinocchios_to_rounding(frame):
    chain = kernel.Chain.of(KIN, frame).packed()
    for q in ANGLES:
        r, p = kernel.frame_pose(q, chain)
        t = KIN.fk(q, frame)
        np.testing.assert_allclose(r, t[:3, :3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(p, t[:3, 3], rtol=0, atol=1e-12)
        np.testing.assert_allclose(kernel.frame_jacobian(q, chain), KIN.jacobian(q, frame), rtol=0, atol=1e-12)


@pytest.mark.parametrize("angle", [0.0, 1e-9, 1e-5, 0.3, 2.0, np.pi - 0.05, np.pi - 1e-3, np.pi])
def test_log3_equals_pinocchios_from_zero_to_a_half_turn(angle):
    rng = np.random.default_rng(int(angle * 1000))
    for _ in range(20):
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        r = pin.exp3(angle * axis)
        got = kernel.log3(r)
        np.testing.assert_allclose(np.linalg.norm(got), angle, atol=1e-7)
        np.testing.assert_allclose(pin.exp3(got), r, atol=1e-7)  # the same rotation (± axis at a half turn)
        if angle < np.pi - 1e-2:
            np.testing.assert_allclose(got, pin.log3(r), rtol=0, atol=1e-12)


def test_solve_equals_lapack_and_flags_a_singular_matrix():
    rng = np.random.default_rng(1)
    for _ in range(20):
        a, b = rng.normal(size=(6, 6)), rng.normal(size=6)
        np.testing.assert_allclose(kernel.solve(a, b), np.linalg.solve(a, b), rtol=1e-10, atol=1e-12)
    assert np.isnan(kernel.solve(np.zeros((6, 6)), np.ones(6))).all()


def test_ik_steps_converge_to_a_pose_and_compliance_is_j_k_inverse_jt():
    chain = kernel.Chain.of(KIN, TCP_FRAME).packed()
    r_task = np.diag([1.0, -1.0, -1.0])
    q = Q_HOME_RAD.copy()
    entry = KIN.fk(q, TCP_FRAME)[:3, 3] + np.array([0.01, -0.02, 0.005])
    for _ in range(8):
        jac, _ = kernel.jacobian_and_compliance(q, KTHETA_LI2023_NM_RAD, r_task, chain)
        q = kernel.ik_step(q, jac, np.zeros(3), entry, r_task, chain)
    t = KIN.fk(q, TCP_FRAME)
    np.testing.assert_allclose(t[:3, 3], entry, atol=1e-12)
    np.testing.assert_allclose(t[:3, :3], r_task, atol=1e-12)
    jac, c_task = kernel.jacobian_and_compliance(q, KTHETA_LI2023_NM_RAD, r_task, chain)
    expected = r_task.T @ JointCompliance(KTHETA_LI2023_NM_RAD).translational_compliance_m_n(KIN.jacobian(q)) @ r_task
    np.testing.assert_allclose(c_task, expected, rtol=1e-12, atol=0)


def test_deflected_marker_follows_the_joint_twist_of_the_tip_load():
    marker_chain = kernel.Chain.of(KIN, TRACKER_FRAME).packed()
    r_task = np.diag([1.0, -1.0, -1.0])
    q = Q_HOME_RAD.copy()
    jac = KIN.jacobian(q)
    force, torque = np.array([3.0, -2.0, 25.0]), 0.04
    dq_kernel = kernel.joint_deflection(jac, force, torque, r_task, KTHETA_LI2023_NM_RAD)
    got = kernel.frame_pose(q + dq_kernel, marker_chain)[1]
    w = np.concatenate([r_task @ force, r_task @ np.array([0.0, 0.0, torque])])
    dq = JointCompliance(KTHETA_LI2023_NM_RAD).joint_deflection_rad(jac, w)
    np.testing.assert_allclose(got, KIN.fk(q + dq, TRACKER_FRAME)[:3, 3], rtol=0, atol=1e-12)
    assert np.linalg.norm(got - KIN.fk(q, TRACKER_FRAME)[:3, 3]) > 1e-6  # the load does move it


def test_kinematics_share_the_parsed_urdf_but_not_their_frames():
    """Each model is a copy of the URDF parsed once: its added frames never reach another model."""
    from drillgym.envs.robot.ur5 import _urdf_model, ur5_urdf_path

    short, long = UR5Kinematics(0.10), UR5Kinematics(0.25)
    tip_short, tip_long = short.position(Q_HOME_RAD), long.position(Q_HOME_RAD)
    flange = short.position(Q_HOME_RAD, "tool0")
    assert np.linalg.norm(tip_long - flange) == pytest.approx(0.25, abs=1e-12)
    assert np.linalg.norm(tip_short - flange) == pytest.approx(0.10, abs=1e-12)
    assert not _urdf_model().existFrame(TCP_FRAME)
    fresh = pin.buildModelFromUrdf(str(ur5_urdf_path()))
    assert _urdf_model() == fresh
