"""The simulated drilling cell: quasi-static UR5 + bending drill + bone.

Composes the arm (Pinocchio kinematics, joint compliance ``J Kθ⁻¹ Jᵀ``), the cantilever drill, the
cutting-force tables and the tip balance (:mod:`drillgym.envs.drilling.contact`). Per agent step the arm's
compliance is refreshed at the current pose; per F/T sample (100 Hz) the tip balance is solved.
Pure numpy + Pinocchio: no PyBullet here.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from drillgym.envs.cell_params import R_BASE_TASK, CellParams
from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.drilling.bone import BonePreset, get_bone_preset
from drillgym.envs.drilling.contact import ContactSample, SampleRow, TipContactSolver
from drillgym.envs.drilling.force_model import EngagementTable
from drillgym.envs.drilling.geometry import DrillGeometry
from drillgym.envs.drilling.hole import Hole
from drillgym.envs.drilling.tool import CantileverTool
from drillgym.envs.read_through import ReadThrough
from drillgym.envs.robot import ur5_kernel
from drillgym.envs.robot.compliance import JointCompliance
from drillgym.envs.robot.ur5 import FLANGE_FRAME, Q_HOME_RAD, TCP_FRAME, TRACKER_FRAME, UR5Kinematics
from drillgym.envs.scenario import Scenario


@functools.lru_cache(maxsize=64)
def _engagement_table(
    geometry: DrillGeometry, bone: BonePreset, beta_rad: float, cortical_m: float, max_depth_m: float
) -> EngagementTable:
    return EngagementTable.build(geometry, bone, beta_rad, cortical_m, max_depth_m)


@functools.lru_cache(maxsize=16)
def _kinematics(tcp_offset_m: float, marker: tuple[float, float, float]) -> UR5Kinematics:
    return UR5Kinematics(tcp_offset_m, marker)


@functools.lru_cache(maxsize=16)
def chains_of(kin: UR5Kinematics) -> tuple[np.ndarray, np.ndarray]:
    """The compiled kernels' chains (:meth:`ur5_kernel.Chain.packed`) to the TCP and to the tracker marker."""
    return ur5_kernel.Chain.of(kin, TCP_FRAME).packed(), ur5_kernel.Chain.of(kin, TRACKER_FRAME).packed()


HARDNESS_FACTOR_LIMITS = (0.5, 1.5)
"""A drawn specimen's hardness factor is clamped to these (relative to its bone preset)."""


def servo_gain(time_constant_s: float) -> float:
    """Share of the way to its target the servo moves per physics update (first-order lag of ``time_constant_s``)."""
    return 1.0 - math.exp(-PHYSICS_DT_S / time_constant_s)


def draw_specimen_hardness(rng: np.random.Generator, variability: float) -> float:
    """A specimen's hardness factor: ``1 + variability · z`` for ``rng``'s next standard normal ``z``, clamped.

    Bone varies from sample to sample; the simulated env (at ``reset(seed)``) and the emulator (per
    specimen seed) draw it the same way, so a seed gives the same specimen in both.
    """
    factor = 1.0 + variability * float(rng.standard_normal())
    low, high = HARDNESS_FACTOR_LIMITS
    return min(max(factor, low), high)


class SimCell(ReadThrough):
    """Quasi-static physics of the UR5 drilling cell for one scenario.

    Attributes (besides the physics):
        servo_gain: the scenario's servo lag as a share per physics update (:func:`servo_gain`).
        specimen_hardness: this specimen's hardness factor (:meth:`set_specimen_hardness`).
    """

    def __init__(self, scenario: Scenario, params: CellParams | None = None, bone: BonePreset | None = None) -> None:
        """Build the cell; ``bone`` overrides the scenario's named preset with a custom specimen."""
        self.scenario = scenario
        self.params = params or CellParams()
        p = self.params
        self.geometry = scenario.geometry
        self.tool = CantileverTool(
            diameter_m=scenario.drill_diameter_m,
            stickout_m=scenario.stickout_m,
            effective_diameter_ratio=p.effective_diameter_ratio,
        )
        self.tcp_offset_m = p.sensor_to_chuck_m + scenario.stickout_m
        self.kin = _kinematics(self.tcp_offset_m, tuple(p.tracker_marker_flange_m))
        self._tcp_chain, self._marker_chain = chains_of(self.kin)
        self.joints = JointCompliance(np.asarray(p.stiffness_nm_rad, dtype=float))
        self.R_base_task = R_BASE_TASK
        self.entry_base_m = p.entry_point
        self.T_base_task = np.eye(4)
        self.T_base_task[:3, :3] = R_BASE_TASK
        self.T_base_task[:3, 3] = self.entry_base_m
        max_depth = scenario.depth_m + 2e-3
        if bone is None:
            bone = get_bone_preset(scenario.bone)
        self.bone = bone.scaled(scenario.density_scale)
        self.table = _engagement_table(
            self.geometry, self.bone, scenario.beta_rad, scenario.cortical_thickness_m, max_depth
        )
        self._tables = {scenario.beta_rad: self.table}
        self.hole = Hole(max_depth)
        self.solver = TipContactSolver(
            self.table,
            self.geometry,
            scenario.beta_rad,
            self.hole,
            p.lateral_cut_resistance_n,
            p.guidance_exponent,
            p.skid_relief,
            p.wall_guidance_floor,
            p.wall_length_m,
        )
        self.C_tool = self.tool.compliance_tool_m_n()
        self.servo_gain = servo_gain(scenario.servo_time_constant_s)
        self.specimen_hardness = 1.0
        self.sample: ContactSample
        """The latest update of the tip balance (set by :meth:`reset`)."""
        self._q_start = self._ik_cached(0.0)
        self.clear_effects()
        self.reset()

    def clear_effects(self) -> None:
        """Undo what unmodelled effects (:mod:`drillgym.envs.effects`) changed: nominal tool, bone, geometry.

        The effect state of the cell: ``geometry_offset_task_m`` (the physical tip and the tool sit this
        far from where the controller's kinematic model puts them, task frame, m; the encoders and the
        RTDE TCP do not see it), ``marker_offset_base_m`` (the same for the tracker marker, base frame, m),
        ``sensor_arm_m`` (F/T origin to the real drill tip, m), ``spindle_rpm`` (the spindle's speed now,
        rpm; it sets the chip thickness), the drill compliance ``C_tool`` and the tip balance's
        ``depth_profile`` and ``guidance_hook``, and the surface's inclination (:meth:`set_surface_angle`).
        """
        self.geometry_offset_task_m: np.ndarray | None = None
        self.spindle_rpm = self.scenario.spindle_rpm
        self.marker_offset_base_m: np.ndarray | None = None
        self.sensor_arm_m = self.tcp_offset_m
        self.set_tool_compliance(self.tool.compliance_tool_m_n())
        self.solver.clear_effects()
        if self.solver.beta_rad != self.scenario.beta_rad:
            self.set_surface_angle(self.scenario.beta_rad)

    def set_surface_angle(self, beta_rad: float) -> None:
        """The bone surface's real inclination β (rad, about the task y axis), whatever the plan says.

        The force table is rebuilt for it (kept per angle: a fit tries the same angles on every episode), the tip
        balance reads its slope and stage bounds, and the tip's local depth is updated where it stands.
        """
        table = self._tables.get(beta_rad)
        if table is None:
            sc = self.scenario
            table = _engagement_table(self.geometry, self.bone, beta_rad, sc.cortical_thickness_m, sc.depth_m + 2e-3)
            if len(self._tables) > 64:
                self._tables = {sc.beta_rad: self._tables[sc.beta_rad]}
            self._tables[beta_rad] = table
        self.table = table
        s = self.solver
        s.set_surface(table, beta_rad)
        s.depth_local = s.tip[2] + s.tip[0] * s.tan_beta
        self.sample = dataclasses.replace(self.sample, depth_local=s.depth_local)

    def set_tool_compliance(self, compliance_tool_m_n: np.ndarray) -> None:
        """Replace the drill's tip compliance (3x3, m/N, tool frame) from now on."""
        self.C_tool = np.asarray(compliance_tool_m_n, dtype=float)
        if hasattr(self, "C_robot"):
            self.C_total = self.C_robot + self.C_tool

    # ------------------------------------------------------------------ poses
    def tip_pose_base(self, tip_task_m: np.ndarray) -> np.ndarray:
        """``T_base_tcp`` for a rigid tip at ``tip_task_m`` with the drill along the planned axis."""
        t = self.T_base_task.copy()
        t[:3, 3] = self.entry_base_m + self.R_base_task @ tip_task_m
        return t

    def _ik_cached(self, depth_m: float) -> np.ndarray:
        return _start_ik(self.kin, tuple(self.tip_pose_base(np.array([0.0, 0.0, depth_m]))[:3, 3]))

    # ------------------------------------------------------------------ episode
    def reset(self, start_tip_task_m: np.ndarray | None = None) -> None:
        """Uncut bone, unloaded arm, tip at ``start_tip_task_m`` (default 3 mm above the entry)."""
        start = np.array([0.0, 0.0, -3e-3]) if start_tip_task_m is None else np.asarray(start_tip_task_m, float)
        self.solver.reset((float(start[0]), float(start[1]), float(start[2])))
        self.q_motor_rad = _start_ik(self.kin, tuple(self.tip_pose_base(start)[:3, 3])).copy()
        self._update_compliance()
        self.sample = ContactSample(tuple(start), tuple(start), (0.0, 0.0, 0.0), 0.0, float(start[2]), 0, False)

    def set_specimen_hardness(self, factor: float) -> None:
        """Cut a specimen ``factor`` times as hard as the bone preset (every cutting force scales with it)."""
        self.specimen_hardness = factor
        self.solver.force_scale = factor

    def _update_compliance(self) -> None:
        """``J_tcp`` and ``C_robot`` (task axes) at the motor angles (compiled: :mod:`~drillgym.envs.robot.ur5_kernel`)."""
        self.J_tcp, self.C_robot = ur5_kernel.jacobian_and_compliance(
            self.q_motor_rad, self.joints.stiffness_nm_rad, self.R_base_task, self._tcp_chain
        )
        self.C_total = self.C_robot + self.C_tool

    def begin_step(self, chip_m: float, advance_per_update_m: float) -> None:
        """Freeze compliance, chip thickness (m) and the axial advance per F/T sample (m)."""
        self.solver.prepare(self.C_total, chip_m, advance_per_update_m)

    def update(self, target_task_m: tuple[float, float, float], servo_gain: float | None = None) -> ContactSample:
        """One F/T sample: servo moves ``servo_gain`` (default: the cell's own) of the way to the target, then the tip balances."""
        self.sample = self.solver.update(target_task_m, self.servo_gain if servo_gain is None else servo_gain)
        return self.sample

    def run(self, targets_task_m: list[tuple[float, float, float]], servo_gain: float | None = None) -> list[SampleRow]:
        """Consecutive F/T samples, one per servo target (task frame, m): :meth:`update` for each, fused.

        Returns the samples as plain rows (fields of :class:`ContactSample`); :attr:`sample` is the last.
        """
        rows = self.solver.run(targets_task_m, self.servo_gain if servo_gain is None else servo_gain)
        if rows:
            self.sample = ContactSample(*rows[-1])
        return rows

    def end_step(self) -> None:
        """Track the servo target with the motor-side joint angles; refresh J and the compliance.

        One Newton step of inverse kinematics from the previous angles per agent step (the target
        moves ≤ 0.5 mm per step, so the residual is < 1 nm).
        """
        rigid = np.array(self.sample.rigid)
        if self.geometry_offset_task_m is not None:
            rigid = rigid - self.geometry_offset_task_m  # where the controller's model puts the tip
        q = ur5_kernel.ik_step(
            self.q_motor_rad, self.J_tcp, rigid, self.entry_base_m, self.R_base_task, self._tcp_chain
        )
        if not np.isfinite(q).all():
            raise np.linalg.LinAlgError(f"singular TCP Jacobian at q = {self.q_motor_rad.tolist()} rad")
        self.q_motor_rad = q
        self._update_compliance()

    @property
    def force(self) -> np.ndarray:
        """External force on the drill at the latest sample (N, task axes)."""
        return np.asarray(self.sample.force)

    @property
    def tip(self) -> np.ndarray:
        """True tip position at the latest sample (m, task frame)."""
        return np.asarray(self.sample.tip)

    @property
    def rigid_tip(self) -> np.ndarray:
        """Servo-held rigid tip at the latest sample (m, task frame)."""
        return np.asarray(self.sample.rigid)

    def tip_deflection_robot_m(self) -> np.ndarray:
        """Tip displacement due to joint compliance, C_robot F (m, task frame)."""
        return self.C_robot @ self.force

    def tip_deflection_tool_m(self) -> np.ndarray:
        """Tip displacement due to drill bending, C_tool F (m, task frame)."""
        return self.C_tool @ self.force

    # ------------------------------------------------------------------ sensing helpers
    def sensor_wrench(self, sample: ContactSample) -> tuple[float, ...]:
        """True wrench on the tool at the F/T sensor origin, sensor frame (task axes): (N, N·m).

        The tip force acts ``tcp_offset`` ahead of the sensor along z: τ = (0, 0, L) × F + M_axis ẑ.
        """
        fx, fy, fz = sample.force
        arm = self.sensor_arm_m
        return (fx, fy, fz, -arm * fy, arm * fx, sample.torque_axis)

    def joint_deflection_rad(self) -> np.ndarray:
        """δq = Kθ⁻¹ Jᵀ W of the current load (rad): what the encoders do not see (:func:`ur5_kernel.joint_deflection`)."""
        smp = self.sample
        return ur5_kernel.joint_deflection(
            self.J_tcp, np.array(smp.force), smp.torque_axis, self.R_base_task, self.joints.stiffness_nm_rad
        )

    def q_actual_rad(self) -> np.ndarray:
        """Link-side joint angles: motor angles plus the elastic twist (rad)."""
        return self.q_motor_rad + self.joint_deflection_rad()

    def tcp_rtde_base_m(self, rigid_task_m: tuple[float, float, float] | None = None) -> np.ndarray:
        """TCP position the controller reports (FK of the motor angles, base frame, m).

        ``rigid_task_m``: the servo-held tip (task frame, m) of an earlier sample; default the latest one.
        """
        rigid = self.rigid_tip if rigid_task_m is None else np.asarray(rigid_task_m)
        if self.geometry_offset_task_m is not None:
            return self.entry_base_m + self.R_base_task @ (rigid - self.geometry_offset_task_m)
        return self.entry_base_m + self.R_base_task @ rigid

    def marker_base_m(self, q_rad: np.ndarray | None = None) -> np.ndarray:
        """Tracker-marker position (base frame, m): the true one (deflected arm) or, given ``q_rad``, the model's."""
        if q_rad is None:
            p = ur5_kernel.frame_pose(self.q_actual_rad(), self._marker_chain)[1]
            return p if self.marker_offset_base_m is None else p + self.marker_offset_base_m
        return self.kin.fk(q_rad, TRACKER_FRAME)[:3, 3]

    def flange_pose_base(self, q_rad: np.ndarray) -> np.ndarray:
        """``T_base_flange`` at ``q_rad``."""
        return self.kin.fk(q_rad, FLANGE_FRAME)


@functools.lru_cache(maxsize=64)
def _start_ik(kin: UR5Kinematics, tip_base: tuple[float, float, float]) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = R_BASE_TASK
    t[:3, 3] = tip_base
    return kin.ik(t, Q_HOME_RAD)
