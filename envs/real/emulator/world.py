"""The emulated robot and cell: a UR5 servo on the quasi-static drilling physics of the simulator.

The physics is the simulator's own (:class:`drillgym.envs.cell.SimCell`, 100 Hz updates, the same per-50-ms
compliance refresh), driven by what the controller program commands instead of by the env: servo
targets (``servoL``), straight moves (``moveL``) and stops. The feed the bone sees is estimated from the
commanded targets' axial speed (their arrival times), as the real bone sees the real motion.
The specimen's hardness is drawn like the simulated env's (:func:`drillgym.envs.cell.draw_specimen_hardness`
from ``default_rng(seed)``), and the servo lag is the cell's, so a seed gives the same specimen in both.

Frames: ``base`` (UR base), ``task`` (planned entry point, z along the drill into the bone), TCP poses
as UR poses of the *configured* TCP (``setTcp``), the physical drill tip at the cell's true TCP offset.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from drillgym.envs.cell import SimCell, draw_specimen_hardness
from drillgym.envs.cell_params import CellParams
from drillgym.envs.constants import FT_TORQUE_NOISE_ARM_M, PHYSICS_DT_S, SUBSTEPS_PER_STEP
from drillgym.envs.drilling.contact import ContactSample
from drillgym.envs.real.emulator.truth import TruthRecorder
from drillgym.envs.real.poses import matrix_to_pose, pose_to_matrix, rotation_angle_rad
from drillgym.envs.scenario import Scenario

HOME_STANDOFF_M = 10e-3
"""The robot starts with the drill tip this far above the planned entry point, on the planned axis (m)."""
MOVE_DONE_TOLERANCE_M = 1e-6
"""A straight move is done when the servo is this close to its end point (m)."""
RETRACTED_M = 1e-3
"""The drill is out of the specimen when its tip is this far above the surface (m): the operator may swap it."""
FEED_WINDOW_S = 0.1
"""Commanded targets over this window give the axial speed the bone sees (s)."""


def _translation(z_m: float) -> np.ndarray:
    t = np.eye(4)
    t[2, 3] = z_m
    return t


class EmulatedCell:
    """Robot + drill + bone of one emulated cell.

    Args:
        scenario: the physical cell (bone, β, drill, stick-out, sensor noise, servo lag).
        seed: specimen seed (the first specimen; each new specimen adds 1).
        params: hardware layout and calibrated physics (the simulator's defaults).
        ft_offset: constant F/T reading with no load (tool weight, drift): N and N·m, sensor frame.
        ft_rate_hz: F/T record rate; per-record noise is scaled so a 100 Hz mean has the scenario's noise.
    """

    def __init__(
        self,
        scenario: Scenario,
        seed: int = 0,
        params: CellParams | None = None,
        ft_offset: tuple[float, ...] = (0.3, -0.2, 2.5, 0.01, -0.02, 0.0),
        ft_rate_hz: float = 500.0,
    ) -> None:
        self.scenario = scenario
        self.cell = SimCell(scenario, params)
        self.R = self.cell.R_base_task
        self.entry = self.cell.entry_base_m
        self.T_tcp_true = _translation(self.cell.tcp_offset_m)
        self.T_tcp_cfg = self.T_tcp_true.copy()
        self.seed = int(seed)
        self.specimen = -1
        self.ft_offset = np.asarray(ft_offset, dtype=float)
        self.ft_external = np.zeros(6)
        self.qd_rad_s = np.zeros(6)
        """Joint velocities behind the TCP velocity (rad/s; J⁻¹ of the TCP twist, J refreshed every agent step)."""
        self.tcp_velocity_base_m_s = np.zeros(3)
        """TCP (rigid tip) velocity over the last physics step (m/s, base frame; the orientation is held)."""
        """A load hung from the tool (control command ``ft_load``): N and N·m, sensor frame."""
        self.ft_bias = np.zeros(6)
        oversample = math.sqrt(max(ft_rate_hz, 100.0) / 100.0)
        noise = scenario.ft_noise_n * oversample
        self.ft_noise_std = np.array([noise] * 3 + [noise * FT_TORQUE_NOISE_ARM_M] * 3)
        self.truth = TruthRecorder()
        self.halted = False
        self.halted_at_s = -math.inf
        """Emulator time (s) of the last protective stop."""
        self.next_specimen_seed: int | None = None
        """The seed a client asked for the next specimen (``control`` command ``specimen``)."""
        self.specimen_seed = self.seed
        self.orientation_warnings = 0
        self.new_specimen(np.array([0.0, 0.0, -HOME_STANDOFF_M]))

    # ------------------------------------------------------------------ specimen
    def new_specimen(self, start_tip_task_m: np.ndarray, seed: int | None = None) -> None:
        """A fresh bone with the tip at ``start_tip_task_m`` (m, task).

        Its seed is ``seed``, else one a client asked for (:meth:`seed_specimen`), else the emulator's seed
        plus the specimen number.
        """
        self.specimen += 1
        sc = self.scenario
        if seed is None:
            seed, self.next_specimen_seed = self.next_specimen_seed, None
        self.specimen_seed = self.seed + self.specimen if seed is None else int(seed)
        self.rng = np.random.default_rng(self.specimen_seed)
        hardness = draw_specimen_hardness(self.rng, sc.bone_variability)
        self.cell.reset(np.asarray(start_tip_task_m, dtype=float))
        self.cell.set_specimen_hardness(hardness)
        self.target_task = np.array(self.cell.rigid_tip)
        self.move: tuple[np.ndarray, np.ndarray, float, float] | None = None
        self.targets: deque[tuple[float, float]] = deque()
        self.tick = 0
        self.truth.clear()

    def seed_specimen(self, seed: int) -> bool:
        """Draw the specimen from ``seed``, as the sim's ``reset(seed=seed)`` does; whether it was drawn now.

        The specimen is replaced at once when it is uncut or the drill is out of it (the tip stays where it
        is); while the drill is in a hole the seeded one comes when the operator changes it, after the retract.
        """
        if self.bone_cut and self.cell.rigid_tip[2] >= -RETRACTED_M:
            self.next_specimen_seed = int(seed)
            return False
        self.new_specimen(np.array(self.cell.rigid_tip), seed=seed)
        return True

    @property
    def hardness_factor(self) -> float:
        """This specimen's drawn hardness factor (the cell's)."""
        return self.cell.specimen_hardness

    @property
    def bone_cut(self) -> bool:
        """Whether this specimen has been cut."""
        return self.cell.hole.deepest_bin >= 0

    # ------------------------------------------------------------------ poses
    def _tip_task_from_tcp(self, tcp_pose: np.ndarray) -> np.ndarray:
        t_target = pose_to_matrix(tcp_pose)
        if rotation_angle_rad(t_target[:3, :3], self.R) > math.radians(2.0):
            self.orientation_warnings += 1
        flange = t_target @ np.linalg.inv(self.T_tcp_cfg)
        tip_base = (flange @ self.T_tcp_true)[:3, 3]
        return self.R.T @ (tip_base - self.entry)

    def tcp_pose(self, tip_task_m: np.ndarray | None = None) -> np.ndarray:
        """UR pose of the configured TCP with the rigid tip at ``tip_task_m`` (default: where the servo is)."""
        tip = self.cell.rigid_tip if tip_task_m is None else np.asarray(tip_task_m, dtype=float)
        t_tip = np.eye(4)
        t_tip[:3, :3] = self.R
        t_tip[:3, 3] = self.entry + self.R @ tip
        return matrix_to_pose(t_tip @ np.linalg.inv(self.T_tcp_true) @ self.T_tcp_cfg)

    def target_q_rad(self) -> np.ndarray:
        """Joint angles of the servo target (rad), leading the reported angles while the arm moves.

        The reported (motor) angles plus the joint step that takes the servo-held tip to the target: J⁻¹ of the tip
        offset in base axes, first order, the orientation held. Equal to the reported angles once the servo arrived.
        """
        q = np.asarray(self.cell.q_motor_rad, dtype=float)
        offset = self.R @ (np.asarray(self.target_task, dtype=float) - np.asarray(self.cell.rigid_tip, dtype=float))
        try:
            step = np.linalg.solve(self.cell.J_tcp, np.concatenate([offset, np.zeros(3)]))
        except np.linalg.LinAlgError:
            return q
        return q + step if np.all(np.isfinite(step)) else q

    def set_tcp(self, tcp_pose: np.ndarray) -> None:
        """Configure the TCP (``setTcp``): a UR pose in the flange frame."""
        self.T_tcp_cfg = pose_to_matrix(tcp_pose)

    # ------------------------------------------------------------------ commands
    def servo_to(self, tcp_pose: np.ndarray, t_arrival_s: float) -> None:
        """New servo target (configured TCP, base frame); ignored while protective-stopped."""
        if self.halted:
            return
        self.move = None
        self.target_task = self._tip_task_from_tcp(tcp_pose)
        self.targets.append((t_arrival_s, float(self.target_task[2])))

    def move_linear(self, tcp_pose: np.ndarray, speed_m_s: float, t_s: float) -> None:
        """Start a straight move at ``speed_m_s`` to ``tcp_pose``; :meth:`move_done` tells when it ends."""
        if self.halted:
            return
        start = np.array(self.cell.rigid_tip)
        end = self._tip_task_from_tcp(tcp_pose)
        duration = float(np.linalg.norm(end - start)) / max(speed_m_s, 1e-6)
        self.move = (start, end, t_s, duration)

    def move_done(self) -> bool:
        """Whether the last straight move has arrived (or was stopped)."""
        if self.move is not None:
            return False
        return float(np.linalg.norm(self.target_task - self.cell.rigid_tip)) < MOVE_DONE_TOLERANCE_M or self.halted

    def stop_motion(self) -> None:
        """Stop where the servo is (``servoStop`` / ``stopL``)."""
        self.move = None
        self.target_task = np.array(self.cell.rigid_tip)

    def protective_stop(self, t_s: float) -> None:
        """Halt at emulator time ``t_s``: the arm stops where it is and ignores motion commands until cleared."""
        self.stop_motion()
        self.halted = True
        self.halted_at_s = t_s

    # ------------------------------------------------------------------ physics
    def physics_tick(self, t_s: float) -> ContactSample:
        """One 10 ms physics update at emulator time ``t_s`` (s)."""
        cell = self.cell
        if self.move is not None:
            start, end, t0, duration = self.move
            frac = 1.0 if duration <= 0 else min(max((t_s - t0) / duration, 0.0), 1.0)
            self.target_task = start + frac * (end - start)
            self.targets.append((t_s, float(self.target_task[2])))
            if frac >= 1.0:
                self.move = None
                if self.bone_cut and self.target_task[2] < -RETRACTED_M:
                    self.new_specimen(self.target_task)  # the operator puts a fresh specimen in
        if self.tick % SUBSTEPS_PER_STEP == 0:
            v = self._axial_speed_m_s(t_s)
            sc = self.scenario
            cell.begin_step(sc.geometry.chip_thickness_m(max(v, 0.0), sc.spindle_rpm), max(v, 0.0) * PHYSICS_DT_S)
        tip_before = np.array(cell.rigid_tip, dtype=float)
        smp = cell.update(tuple(self.target_task.tolist()))
        self.tcp_velocity_base_m_s = self.R @ (np.array(cell.rigid_tip, dtype=float) - tip_before) / PHYSICS_DT_S
        twist = np.concatenate([self.tcp_velocity_base_m_s, np.zeros(3)])
        self.qd_rad_s = np.linalg.solve(cell.J_tcp, twist)  # the joint rates behind that TCP velocity
        self.tick += 1
        if self.tick % SUBSTEPS_PER_STEP == 0:
            cell.end_step()
        self.truth.record(t_s, smp)
        return smp

    def _axial_speed_m_s(self, t_s: float) -> float:
        while self.targets and self.targets[0][0] < t_s - FEED_WINDOW_S:
            self.targets.popleft()
        if len(self.targets) < 2:
            return 0.0
        (t0, z0), (t1, z1) = self.targets[0], self.targets[-1]
        return (z1 - z0) / (t1 - t0) if t1 - t0 > 0.02 else 0.0

    # ------------------------------------------------------------------ sensing
    def ft_reading(self) -> np.ndarray:
        """One F/T reading: true wrench + noise + offset − bias (N, N·m, sensor frame)."""
        w = np.asarray(self.cell.sensor_wrench(self.cell.sample), dtype=float)
        return w + self.ft_noise_std * self.rng.standard_normal(6) + self.ft_offset + self.ft_external - self.ft_bias

    def bias_ft(self) -> None:
        """RDT software bias: zero the current (filtered, noise-free) reading."""
        w = np.asarray(self.cell.sensor_wrench(self.cell.sample), dtype=float)
        self.ft_bias = w + self.ft_offset + self.ft_external

    def marker_reading(self) -> np.ndarray:
        """Tracker marker position (m, base frame) of the deflected arm, with the scenario's noise."""
        true = self.cell.marker_base_m()
        return true + self.scenario.tracker_noise_m * self.rng.standard_normal(3)

    def tcp_force_base(self) -> np.ndarray:
        """Wrench at the TCP in base axes (what a CB3 estimates from joint currents): N, N·m."""
        f = self.R @ self.cell.force
        tau = self.R @ np.array([0.0, 0.0, self.cell.sample.torque_axis])
        return np.concatenate([f, tau])
