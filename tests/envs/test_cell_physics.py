"""The simulated cell against independent formulas and Li 2023's figures."""

import gymnasium as gym
import numpy as np
import pytest
from physics_helpers import ENV_ID, r_squared, run_zero_action

from drillgym.envs.cell import SimCell
from drillgym.envs.cell_params import CellParams
from drillgym.envs.constants import unscale_action
from drillgym.envs.pybullet_world import PyBulletWorld
from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD
from drillgym.envs.robot.ur5 import FLANGE_FRAME
from drillgym.envs.scenario import Scenario
from drillgym.eval.reproduce.paper import CALIBRATION_TOLERANCE, LI2023_UNCOMPENSATED

POSES_BASE_M = [
    (-0.45, -0.11, 0.10),
    (-0.50, -0.11, 0.15),
    (-0.40, -0.20, 0.05),
    (-0.35, 0.10, 0.12),
    (-0.55, -0.25, 0.20),
    (-0.30, -0.30, 0.08),
]


@pytest.fixture(scope="module")
def world():
    w = PyBulletWorld()
    yield w
    w.close()


@pytest.mark.parametrize("entry", POSES_BASE_M)
def test_static_tip_deflection_matches_j_ktheta_inv_jt_f_under_pybullet_kinematics(world, entry):
    # The cell bends the arm by dq = Ktheta^-1 J^T W and moves the tip by C F with C = J Ktheta^-1 J^T.
    # PyBullet's own forward kinematics of the same URDF, at the deflected joint angles, must agree.
    cell = SimCell(Scenario(), CellParams(entry_point_base_m=entry))
    q0 = cell.q_motor_rad
    j = cell.kin.jacobian(q0)
    for force_base in ([20.0, 0, 0], [0, -20.0, 0], [0, 0, 30.0], [10.0, 10.0, -10.0]):
        w = np.concatenate([force_base, np.zeros(3)])
        dq = cell.joints.joint_deflection_rad(j, w)
        predicted = cell.joints.translational_compliance_m_n(j) @ np.asarray(force_base)

        def tip(q):
            world.set_joint_angles(q)
            t = world.link_pose_base(FLANGE_FRAME)
            return t[:3, 3] + t[:3, 2] * cell.tcp_offset_m

        measured = tip(q0 + dq) - tip(q0)
        assert np.linalg.norm(measured - predicted) <= 0.02 * np.linalg.norm(predicted)


def test_pinocchio_and_pybullet_agree_on_the_tcp_pose(world):
    cell = SimCell(Scenario())
    q = cell.q_motor_rad + np.array([0.1, -0.05, 0.08, 0.2, -0.1, 0.3])
    world.set_joint_angles(q)
    t_pb = world.link_pose_base(FLANGE_FRAME)
    t_pin = cell.kin.fk(q, FLANGE_FRAME)
    np.testing.assert_allclose(t_pb, t_pin, atol=1e-6)


def test_robot_compliance_magnitude_is_that_of_li_ktheta():
    # Li's K_theta gives 0.006-0.026 mm/N at a typical drilling pose (29-199 N/mm principal stiffnesses);
    # our pose holds the tool 146 mm from the flange, slightly stiffer in its stiffest direction.
    cell = SimCell(Scenario())
    eig = np.linalg.eigvalsh(cell.C_robot) * 1e3  # mm/N
    assert 0.003 <= eig.min() and eig.max() <= 0.035


def test_perpendicular_drilling_has_no_lateral_force_in_the_stable_stage():
    # The cutting forces are balanced (exactly, see test_force_model); what is left is the arm's
    # thrust-to-lateral coupling (C_yz ~ 12 um/N x 7.5 N of thrust) pressing the drill on the wall.
    m = run_zero_action(0, beta_deg=0.0, ft_noise_n=0.0).metrics
    inclined = run_zero_action(0, beta_deg=30.0, ft_noise_n=0.0).metrics
    assert m["lateral_force_stable_n"] < 0.1 * inclined["lateral_force_stable_n"]
    assert m["deviation_mean_mm"] < 0.1


@pytest.mark.parametrize(("stiffness_scale", "rel"), [(1e3, 0.01), (1.0, 0.10)])
def test_mirrored_beta_gives_the_same_deviation_turned_half_a_turn(stiffness_scale, rel):
    # With a (nearly) rigid arm, beta -> -beta is the same problem turned by pi about the drill axis.
    # Li's compliant arm breaks the symmetry a little: thrust pushes the tip sideways (C_yz) the same
    # way for both signs, adding to the tangential push for one and opposing it for the other.
    params = CellParams(stiffness_nm_rad=KTHETA_LI2023_NM_RAD * stiffness_scale)
    kw = {"ft_noise_n": 0.0, "bone_variability": 0.0, "cell_params": params}
    a = run_zero_action(0, beta_deg=20.0, **kw)
    b = run_zero_action(0, beta_deg=-20.0, **kw)
    assert a.metrics["deviation_mean_mm"] == pytest.approx(b.metrics["deviation_mean_mm"], rel=rel)
    assert a.metrics["hole_offset_mm"] == pytest.approx(b.metrics["hole_offset_mm"], rel=rel)
    fa, fb = a.trace["ft_force_n"], b.trace["ft_force_n"]
    i = int(np.argmax(np.hypot(fa[:, 0], fa[:, 1])))
    assert np.sign(fa[i, 0]) == -np.sign(fb[i, 0])  # uphill sides are opposite: so are the skids


def test_li_fig9b_deviated_hole_keeps_loading_the_drill_in_the_stable_stage():
    m = run_zero_action(0).metrics
    assert m["lateral_force_stable_n"] >= 0.7 * m["lateral_force_max_n"]  # paper: 1.2 N vs 1.3 N


def test_an_entry_deviation_is_locked_in_by_the_hole():
    r = run_zero_action(0, ft_noise_n=0.0)
    feeding = r.trace["phase"] == 1
    end_dev = r.trace["deviation_m"][feeding][-1] * 1e3
    assert end_dev >= 0.7 * r.metrics["hole_offset_mm"]


def test_stages_progress_one_to_four_during_entry():
    r = run_zero_action(0)
    stages = r.trace["stage"][r.trace["phase"] == 1]
    seen = [s for i, s in enumerate(stages) if i == 0 or s != stages[i - 1]]
    assert seen == [0, 1, 2, 3, 4]


@pytest.mark.expensive
def test_full_sim_max_lateral_force_grows_with_beta_and_linearly_with_feed():
    betas = np.array([0.0, 5.0, 10.0, 15.0, 20.0])
    f_beta = np.array([run_zero_action(0, beta_deg=b, ft_noise_n=0.0).metrics["lateral_force_max_n"] for b in betas])
    assert np.all(np.diff(f_beta) > 0)
    assert r_squared(betas, f_beta) >= 0.95
    feeds = np.linspace(0.25, 1.25, 5)
    f_feed = np.array([run_zero_action(0, feed_mm_s=c, ft_noise_n=0.0).metrics["lateral_force_max_n"] for c in feeds])
    assert r_squared(feeds, f_feed) >= 0.95


def test_calibrated_uncompensated_paper_run_matches_li_over_five_seeds():
    """Tolerances: ``CALIBRATION_TOLERANCE``, whose docstring gives their reasons. Measured (seeds 0-4):
    deviation 0.717 mm (+2.0 %), peak lateral force 1.316 N (+1.2 %), both fitted, within 5 %; stable force
    0.994 N (-17 %) and hole offset 0.786 mm (-1.8 %), predicted, within 25 %."""
    runs = [run_zero_action(seed).metrics for seed in range(5)]
    for name, paper in LI2023_UNCOMPENSATED.items():
        mean = float(np.mean([m[name] for m in runs]))
        assert abs(mean - paper) / paper <= CALIBRATION_TOLERANCE[name], (name, mean, paper)


def _hole_and_peak_with_constant_offset(offset_uphill_m: float) -> tuple[np.ndarray, float]:
    """Hole centre at the entry (task x, y; m) and peak lateral force (N), servo held off the plan by a constant."""
    env = gym.make(ENV_ID)
    try:
        env.reset(seed=0)
        action = unscale_action(env.unwrapped.plan.R_base_task @ np.array([offset_uphill_m, 0.0, 0.0]), 1.0)
        while True:
            _, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
        cell = env.unwrapped.cell
        centre = np.asarray(cell.hole.centre_at(env.unwrapped.scenario.entry_depth_m), dtype=float)
        return centre, float(info["metrics"]["lateral_force_max_n"])
    finally:
        env.close()


def test_a_constant_offset_moves_the_hole_but_not_the_entry_force_on_a_planar_slope():
    # A plane is invariant under translation along itself: a drill held a constant distance uphill meets
    # the surface a little earlier and then lives through the same entry, so the hole moves with the
    # offset and the skid-and-catch force stays. (Why a compensator must vary in time to lower the peak.)
    offset_m = 0.4e-3
    c0, f0 = _hole_and_peak_with_constant_offset(0.0)
    c1, f1 = _hole_and_peak_with_constant_offset(offset_m)
    assert f1 == pytest.approx(f0, rel=0.02)
    assert c1[0] - c0[0] == pytest.approx(offset_m, rel=0.05)
    assert c1[1] == pytest.approx(c0[1], abs=0.02e-3)


def test_with_a_wall_floor_of_one_guidance_is_the_lips_alone():
    solver = SimCell(Scenario(), CellParams(wall_guidance_floor=1.0)).solver
    for depth in (0.0, 1e-3, 5e-3):
        solver.depth_local = depth
        assert solver._wall_factor() == 1.0


def test_wall_guidance_rises_from_its_floor_to_full_over_the_wall_length():
    # Before the drill's full diameter is in there is no hole wall: the lips alone give the floor share of
    # the side guidance; it then grows linearly to 1 over wall_length_m of full-diameter hole.
    p = CellParams(wall_guidance_floor=0.03, wall_length_m=1e-3)
    solver = SimCell(Scenario(), p).solver
    full_in = solver._bounds[3]
    for depth, expected in [
        (0.0, p.wall_guidance_floor),
        (full_in, p.wall_guidance_floor),
        (full_in + 0.5 * p.wall_length_m, 0.5 * (1.0 + p.wall_guidance_floor)),
        (full_in + p.wall_length_m, 1.0),
        (full_in + 3.0 * p.wall_length_m, 1.0),
    ]:
        solver.depth_local = depth
        assert solver._wall_factor() == pytest.approx(expected)
    with pytest.raises(ValueError, match="wall_guidance_floor"):
        SimCell(Scenario(), CellParams(wall_guidance_floor=0.0))


def test_a_specimen_hardness_is_one_plus_variability_times_a_normal_draw_clamped():
    from drillgym.envs.cell import HARDNESS_FACTOR_LIMITS, draw_specimen_hardness

    z = np.random.default_rng(7).standard_normal(2)
    assert draw_specimen_hardness(np.random.default_rng(7), 0.05) == 1.0 + 0.05 * z[0]
    low, high = HARDNESS_FACTOR_LIMITS
    for seed in range(20):
        expected = float(np.clip(1.0 + 2.0 * np.random.default_rng(seed).standard_normal(), low, high))
        assert draw_specimen_hardness(np.random.default_rng(seed), 2.0) == expected
    draws = {draw_specimen_hardness(np.random.default_rng(s), 2.0) for s in range(20)}
    assert {low, high} <= draws  # a large variability reaches both clamps


def test_the_servo_gain_is_a_first_order_lag_per_physics_update():
    from drillgym.envs.cell import servo_gain
    from drillgym.envs.constants import PHYSICS_DT_S

    tau = 0.02
    remaining = (1.0 - servo_gain(tau)) ** 10  # ten updates
    assert remaining == pytest.approx(np.exp(-10 * PHYSICS_DT_S / tau), rel=1e-12)


def test_the_pybullet_urdf_copy_is_one_file_per_content_across_processes():
    # Its name must not depend on the process (``hash`` of a str is salted per interpreter): a file per process
    # would pile up in the temp folder, one per env-creating process of every run.
    import subprocess
    import sys

    code = "from drillgym.envs.pybullet_world import pybullet_ur5_urdf; print(pybullet_ur5_urdf(False))"
    paths = {
        subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
        for _ in range(2)
    }
    assert len(paths) == 1
