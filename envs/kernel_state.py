"""The compiled step's arrays (:mod:`drillgym.envs.step_kernel`) for the env's state, and back.

The single env keeps its state in Python objects (the cell, the path, the tip balance, the queue of
commands), which unmodelled effects and the rest of the project read and change. Without effects, or
with only compiled ones (:attr:`Effect.compiled <drillgym.envs.effects.base.Effect.compiled>`; their
parameters go into the episode's ``par``, :data:`STEP_EFFECTS` for those with a step hook), its step runs :func:`~drillgym.envs.step_kernel.advance`: :class:`KernelState` copies the state in
(:meth:`~KernelState.load`), the kernel advances it, and :meth:`~KernelState.store` copies it back, so
every reader sees what the Python step would have left. The batched env builds the same arrays for N
episodes (:mod:`drillgym.envs.batched`) from each episode's :class:`KernelState`, and shares :func:`draw_noise`
and :func:`record_channels` with it.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from drillgym.envs import step_kernel as sk
from drillgym.envs.cell import SimCell, chains_of
from drillgym.envs.constants import PHYSICS_DT_S, SUBSTEPS_PER_STEP, TRACKER_RATE_HZ
from drillgym.envs.drilling.contact import ContactSample
from drillgym.envs.drilling.force_model import EngagementTable
from drillgym.envs.effects.backlash import JointBacklash
from drillgym.envs.effects.base import Effect
from drillgym.envs.effects.bone import ThermalSoftening
from drillgym.envs.effects.joints import JointFriction
from drillgym.envs.effects.spindle import SpindleSag
from drillgym.envs.effects.timing import Latency
from drillgym.envs.task import Phase

UR5BoneDrillEnv = Any
"""The env whose state the arrays hold (:class:`drillgym.envs.drill_env.UR5BoneDrillEnv`; not imported: it imports this module)."""


NOISE_SIZE = 6 * SUBSTEPS_PER_STEP + 3
"""Standard normals a step may read: the F/T's (5x6), then the tracker's (3)."""


def table_rows(table: EngagementTable, depth_profile: np.ndarray | None = None) -> np.ndarray:
    """The force table as :data:`~drillgym.envs.step_kernel.TABLE_ROWS` rows, with the depth profile's factors."""
    n = table.depth_m.shape[0]
    tab = np.zeros((sk.TABLE_ROWS, n))
    tab[0, :n] = table.depth_m
    tab[1:5, :n] = table.edge.T
    tab[5:9, :n] = table.per_chip.T
    tab[9, :n] = table.engaged_fraction
    tab[10, :n] = 1.0 if depth_profile is None else depth_profile
    return tab


def episode_params(
    cell: SimCell,
    latency_s: float,
    force_limit_n: float,
    max_time_s: float,
    marker_start_base_m: np.ndarray,
    s_start_m: float,
    ft_noise_std: np.ndarray,
    tracker_noise_m: float,
) -> np.ndarray:
    """An episode's constant parameters (:data:`~drillgym.envs.step_kernel.PARAM_SIZE`) for the cell as it is now."""
    sc, solver, geo = cell.scenario, cell.solver, cell.geometry
    par = np.zeros(sk.PARAM_SIZE)
    par[sk.LATENCY_S] = latency_s
    par[sk.SERVO_GAIN] = cell.servo_gain
    par[sk.TAN_BETA] = solver.tan_beta
    par[sk.K_LAT] = solver.k_lat_n
    par[sk.GUIDANCE_EXPONENT] = solver.guidance_exponent
    par[sk.WALL_FLOOR] = solver.wall_floor
    par[sk.WALL_LENGTH] = solver.wall_length_m
    par[sk.FORCE_SCALE] = solver.force_scale
    par[sk.TRACKER_NOISE] = tracker_noise_m
    par[sk.FORCE_LIMIT] = force_limit_n
    par[sk.SENSOR_ARM] = cell.sensor_arm_m
    par[sk.DEPTH] = sc.depth_m
    par[sk.FEED_M_S] = sc.feed_m_s
    par[sk.MAX_TIME_S] = max_time_s
    par[sk.N_LIPS] = geo.n_lips
    par[sk.REV_PER_S] = sc.spindle_rpm / 60.0
    par[sk.SIN_KAPPA] = math.sin(geo.kappa_rad)
    par[sk.R_BASE_TASK : sk.R_BASE_TASK + 9] = cell.R_base_task.ravel()
    par[sk.ENTRY_BASE : sk.ENTRY_BASE + 3] = cell.entry_base_m
    par[sk.C_TOOL : sk.C_TOOL + 9] = cell.C_tool.ravel()
    par[sk.STIFFNESS : sk.STIFFNESS + 6] = cell.joints.stiffness_nm_rad
    par[sk.MARKER_START : sk.MARKER_START + 3] = marker_start_base_m
    par[sk.S_START] = s_start_m
    par[sk.BOUNDS : sk.BOUNDS + 4] = solver._bounds
    par[sk.FT_STD : sk.FT_STD + 6] = ft_noise_std
    par[sk.N_GRID] = solver.grid.shape[0]
    par[sk.N_BINS] = cell.hole.filled.shape[0]
    par[sk.BIN_M] = cell.hole.bin_m
    par[sk.OMEGA] = 2.0 * math.pi * sc.spindle_rpm / 60.0
    if cell.geometry_offset_task_m is not None:  # the offsets themselves are state (``load``)
        par[sk.GEOMETRY_ON] = par[sk.TARGET_OFFSET_ON] = 1.0
    if cell.marker_offset_base_m is not None:
        par[sk.MARKER_ON] = 1.0
    par[sk.ENTRY_GUIDANCE] = solver.entry_guidance
    return par


def _thermal_softening(effect: Effect, par: np.ndarray) -> None:
    par[sk.SOFTENING] = effect.values["softening"]
    par[sk.SOFTENING_WORK_J] = effect.values["work_j"]


def _joint_friction(effect: Effect, par: np.ndarray) -> None:
    c, tv = effect.values["coulomb_rad"], effect.values["viscous_s"]
    par[sk.FRICTION_COULOMB], par[sk.FRICTION_VISCOUS] = c, tv
    if c != 0.0 or tv != 0.0:
        par[sk.FRICTION_ON] = par[sk.TARGET_OFFSET_ON] = 1.0


def _joint_backlash(effect: Effect, par: np.ndarray) -> None:
    half = 0.5 * effect.values["play_rad"]
    par[sk.BACKLASH_HALF] = half
    if half > 0.0:  # the links move the tool and the marker from the first step on
        par[sk.GEOMETRY_ON] = par[sk.MARKER_ON] = par[sk.TARGET_OFFSET_ON] = 1.0


def _latency(effect: Effect, par: np.ndarray) -> None:
    par[sk.EXTRA_LATENCY] = effect.values["extra_latency_s"]


def _spindle_sag(effect: Effect, par: np.ndarray) -> None:
    par[sk.SPINDLE_SAG] = effect.values["sag_per_nm"]


STEP_EFFECTS: dict[str, Callable[[Effect, np.ndarray], None]] = {
    ThermalSoftening.name: _thermal_softening,
    JointFriction.name: _joint_friction,
    JointBacklash.name: _joint_backlash,
    Latency.name: _latency,
    SpindleSag.name: _spindle_sag,
}
"""The effects with a step hook the compiled step runs, by name: each writes its parameters into ``par``
(the kernel's counterparts: ``step_kernel._soften``, ``step_kernel._friction_lag``, ``step_kernel._backlash``,
``step_kernel._delayed``,
the spindle share in ``step_kernel.advance``)."""


def tracker_sample_is_new(t_s: Any, stamp_s: Any) -> Any:
    """Whether the step starting at ``t_s`` ends with a new tracker sample (the last one was at ``stamp_s``).

    Floats or arrays of them (one per episode); the end time is the kernel's sum, term by term.
    """
    for _ in range(SUBSTEPS_PER_STEP):
        t_s = t_s + PHYSICS_DT_S
    return np.floor(t_s * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ != stamp_s  # sensors.latest_sample_time_s


def draw_noise(rng: np.random.Generator, noise: np.ndarray, par: np.ndarray, tracker_new: bool) -> None:
    """The step's standard normals into ``noise`` from the episode's generator, in the Python step's order.

    The F/T's (5x6) if it is noisy, then the tracker's (3) if it is noisy and its sample is new (``par``:
    the episode's parameters).
    """
    nf = 6 * SUBSTEPS_PER_STEP
    if par[sk.FT_STD] > 0:
        rng.standard_normal(out=noise[:nf])
    if par[sk.TRACKER_NOISE] > 0 and tracker_new:
        rng.standard_normal(out=noise[nf:])


def record_channels(rows: np.ndarray) -> dict[str, np.ndarray]:
    """The recorder's channels (:class:`~drillgym.envs.metrics.EpisodeRecorder`) in sample rows of the kernel's ``out``."""
    return {
        "t_s": rows[:, sk.OUT_T_S],
        "phase": rows[:, sk.OUT_PHASE].astype(np.int64),
        "stage": rows[:, sk.OUT_STAGE].astype(np.int64),
        "depth_cmd_m": rows[:, sk.OUT_DEPTH_CMD],
        "deviation_m": rows[:, sk.OUT_DEVIATION],
        "tip_task_m": rows[:, sk.OUT_TIP : sk.OUT_TIP + 3],
        "ft_force_n": rows[:, sk.OUT_FORCE : sk.OUT_FORCE + 3],
        "ft_torque_nm": rows[:, sk.OUT_TORQUE : sk.OUT_TORQUE + 3],
        "tracker_deviation_m": rows[:, sk.OUT_TRACKER_DEVIATION],
    }


PHASES = tuple(Phase)
"""The path phases by code."""


class KernelState:
    """The compiled step's arrays for one env's episode (built at ``reset``, without effects or with compiled ones).

    The arrays hold the episode's state from the first step on; after each step :meth:`store` writes it into
    the env's Python objects, which the observation, the info and every other reader use. Nothing in the
    project changes those objects between steps; code that does so by hand must set
    ``UR5BoneDrillEnv.use_compiled_step = False`` (the Python step reads them afresh every step).
    """

    def __init__(self, env: UR5BoneDrillEnv) -> None:
        cell = env.cell
        if cell.solver.guidance_hook is not None:
            raise ValueError("the compiled step has no guidance hook; step this env in Python")
        hole = cell.hole
        fs = np.zeros(sk.FLOAT_STATE_SIZE)
        fs[sk.KEY_CHIP] = math.nan
        self.arrays = sk.KernelArrays(
            fs=fs,
            ist=np.zeros(sk.INT_STATE_SIZE, dtype=np.int64),
            pend=np.zeros((sk.PENDING_ROWS, 5)),
            par=episode_params(
                cell,
                env.scenario.latency_s,
                env.scenario.force_limit_n,
                env.max_time_s,
                env.marker_start_base,
                env.s_start_m,
                env.ft._noise_std,
                env.tracker.noise_m,
            ),
            tab=table_rows(cell.table, cell.solver.depth_profile),
            rows=np.empty((cell.solver.grid.shape[0], 4)),
            chains=np.stack(chains_of(cell.kin)),
            centre=hole.centre_xy_m,
            filled=hole.filled,
            bins=hole.bins,
            delay=np.zeros((sk.DELAY_ROWS, 4)),
        )
        self.fs, self.ist, self.pend, self.par = fs, self.arrays.ist, self.arrays.pend, self.arrays.par
        effects = [] if env.effects is None else env.effects.effects
        if env.effects is not None and not env.effects.compiled:
            raise ValueError(f"the compiled step does not run all of {effects!r}; step this env in Python")
        for e in effects:
            hook = STEP_EFFECTS.get(type(e).name)
            if hook is not None:
                hook(e, self.par)
        self._thermal = next((e for e in effects if isinstance(e, ThermalSoftening)), None)
        backlash = next((e for e in effects if isinstance(e, JointBacklash)), None)
        self._backlash = backlash if self.par[sk.BACKLASH_HALF] > 0.0 else None
        self.noise = np.zeros(NOISE_SIZE)
        self.command = np.zeros(4)
        self.loaded = False

    def step(self, env: UR5BoneDrillEnv, correction_base_m: np.ndarray, feed_scale: float) -> np.ndarray:
        """Advance ``env`` by one agent step of ``command``; the step's sample rows (5, ``OUT_COLUMNS``)."""
        if not self.loaded:
            self.load(env)
        t_apply = env.t_s + env.scenario.latency_s  # as the kernel queues it
        cmd = self.command
        cmd[:3] = correction_base_m
        cmd[3] = feed_scale
        draw_noise(env.np_random, self.noise, self.par, tracker_sample_is_new(env.t_s, env.tracker_stamp))
        out = np.empty((SUBSTEPS_PER_STEP, sk.OUT_COLUMNS))
        sk.advance(*self.arrays, cmd, self.noise, out)
        if self.ist[sk.SINGULAR]:
            raise np.linalg.LinAlgError(f"singular TCP Jacobian at q = {env.cell.q_motor_rad.tolist()} rad")
        env.pending.append((t_apply, correction_base_m, feed_scale))
        self.store(env)
        return out

    @property
    def noiseless(self) -> bool:
        """Whether the episode's F/T and tracker have no noise (a step then draws nothing)."""
        return not (self.par[sk.FT_STD : sk.FT_STD + 6] > 0.0).any() and not self.par[sk.TRACKER_NOISE] > 0.0

    def open_loop(self, env: UR5BoneDrillEnv, commands: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """Advance ``env`` through ``commands`` (T, 4: correction m base frame, feed scale) in one call.

        Noiseless episodes only. Returns the steps taken, the motor angles (T, 6) and tracker readings (T, 3)
        after each step (NaN past the end) and the steps' sample rows (5 per step, ``OUT_COLUMNS``).
        """
        if not self.noiseless:
            raise ValueError("an open-loop call draws no noise: the episode's sensors must be noiseless")
        if not self.loaded:
            self.load(env)
        n = len(commands)
        out = np.empty((SUBSTEPS_PER_STEP * n, sk.OUT_COLUMNS))
        q = np.full((n, 6), math.nan)
        tracker = np.full((n, 3), math.nan)
        done = sk.advance_open_loop(*self.arrays, np.ascontiguousarray(commands, dtype=float), out, q, tracker)
        if self.ist[sk.SINGULAR]:
            raise np.linalg.LinAlgError(
                f"singular TCP Jacobian at q = {self.fs[sk.Q_MOTOR : sk.Q_MOTOR + 6].tolist()} rad"
            )
        pend = self.pend
        env.pending.clear()
        for k in range(self.ist[sk.PENDING]):  # the queue as the kernel left it: every command applied was popped
            env.pending.append((float(pend[k, 0]), pend[k, 1:4].copy(), float(pend[k, 4])))
        env.correction_base_m = self.fs[sk.CORRECTION : sk.CORRECTION + 3].copy()
        self.store(env)
        return done, q, tracker, out[: SUBSTEPS_PER_STEP * done]

    def load(self, env: UR5BoneDrillEnv) -> None:
        """Copy the env's state into the arrays (at the episode's first step)."""
        fs, ist, cell, solver = self.fs, self.ist, env.cell, env.cell.solver
        fs[sk.T_S] = env.t_s
        fs[sk.PATH_S] = env.path.s_m
        fs[sk.FEED_SCALE] = env.feed_scale
        fs[sk.CORRECTION : sk.CORRECTION + 3] = env.correction_base_m
        fs[sk.SOLVER : sk.SOLVER + 8] = [*solver.rigid, *solver.tip, solver.bottom_z, solver.depth_local]
        fs[sk.RTDE_TCP : sk.RTDE_TCP + 3] = env.rtde_tcp_base
        fs[sk.TRACKER_STAMP] = env.tracker_stamp
        fs[sk.TRACKER_READING : sk.TRACKER_READING + 3] = env.tracker_reading
        fs[sk.Q_MOTOR : sk.Q_MOTOR + 6] = cell.q_motor_rad
        fs[sk.JACOBIAN : sk.JACOBIAN + 36] = cell.J_tcp.ravel()
        fs[sk.C_ROBOT : sk.C_ROBOT + 9] = cell.C_robot.ravel()
        self.par[sk.FORCE_SCALE] = solver.force_scale
        fs[sk.FORCE_SCALE_NOW] = solver.force_scale
        fs[sk.SPINDLE_SHARE] = cell.spindle_rpm / cell.scenario.spindle_rpm
        if cell.geometry_offset_task_m is not None:
            fs[sk.GEOMETRY_OFFSET : sk.GEOMETRY_OFFSET + 3] = cell.geometry_offset_task_m
        if cell.marker_offset_base_m is not None:
            fs[sk.MARKER_OFFSET : sk.MARKER_OFFSET + 3] = cell.marker_offset_base_m
        fs[sk.TARGET_OFFSET : sk.TARGET_OFFSET + 3] = fs[sk.GEOMETRY_OFFSET : sk.GEOMETRY_OFFSET + 3]
        if self._backlash is not None:
            fs[sk.LINK_Q : sk.LINK_Q + 3] = self._backlash.q_link[:3]
            fs[sk.LINK_TIP : sk.LINK_TIP + 3], fs[sk.LINK_MARKER : sk.LINK_MARKER + 3] = self._backlash.share
        smp = cell.sample
        o = sk.SAMPLE
        fs[o : o + 10] = [*smp.tip, *smp.rigid, *smp.force, smp.torque_axis]
        fs[o + 10 : o + 13] = smp.depth_local, smp.stage, 1.0 if smp.cutting else 0.0
        if self._thermal is not None:
            fs[sk.WORK_J] = self._thermal.work_j
        ist[sk.PHASE] = int(env.path.phase)
        ist[sk.TOUCHING] = 1 if solver.touching else 0
        ist[sk.BRACKET] = solver._j
        ist[sk.FAILURE] = 0 if env.failure is None else 1
        ist[sk.STEPS] = env.steps
        ist[sk.PENDING] = len(env.pending)
        for k, (t_apply, corr, scale) in enumerate(env.pending):
            self.pend[k, 0] = t_apply
            self.pend[k, 1:4] = corr
            self.pend[k, 4] = scale
        self.loaded = True

    def store(self, env: UR5BoneDrillEnv) -> None:
        """Copy the arrays back into the env's state (its queue has the step's command appended already)."""
        fs, cell, solver = self.fs, env.cell, env.cell.solver
        v = fs.tolist()
        i = self.ist.tolist()
        env.t_s = v[sk.T_S]
        env.path.s_m = v[sk.PATH_S]
        env.path.phase = PHASES[i[sk.PHASE]]
        env.feed_scale = v[sk.FEED_SCALE]
        pending = env.pending
        for _ in range(len(pending) - i[sk.PENDING]):  # the commands applied: the last one is in effect
            env.correction_base_m = pending.popleft()[1]
        o = sk.SOLVER
        solver.rigid, solver.tip = v[o : o + 3], v[o + 3 : o + 6]
        solver.bottom_z, solver.depth_local = v[o + 6], v[o + 7]
        solver.touching, solver._j = i[sk.TOUCHING] == 1, i[sk.BRACKET]
        o = sk.SAMPLE
        solver.force, solver.torque = v[o + 6 : o + 9], v[o + 9]
        cell.sample = ContactSample(
            (v[o], v[o + 1], v[o + 2]),
            (v[o + 3], v[o + 4], v[o + 5]),
            (v[o + 6], v[o + 7], v[o + 8]),
            v[o + 9],
            v[o + 10],
            int(v[o + 11]),
            v[o + 12] == 1.0,
        )
        env.rtde_tcp_base = fs[sk.RTDE_TCP : sk.RTDE_TCP + 3].copy()
        env.ft_last = fs[sk.FT_LAST : sk.FT_LAST + 6].copy()
        env.ft_mean = fs[sk.FT_MEAN : sk.FT_MEAN + 6].copy()
        env.tracker_stamp = v[sk.TRACKER_STAMP]
        env.tracker_reading = fs[sk.TRACKER_READING : sk.TRACKER_READING + 3].copy()
        env.tracker_error_base = fs[sk.TRACKER_ERROR : sk.TRACKER_ERROR + 3].copy()
        env.tracker_lateral_m = v[sk.TRACKER_LATERAL]
        env.step_deviation_m = v[sk.STEP_DEVIATION]
        env.step_lateral_n = v[sk.STEP_LATERAL]
        cell.q_motor_rad = fs[sk.Q_MOTOR : sk.Q_MOTOR + 6].copy()
        cell.J_tcp = fs[sk.JACOBIAN : sk.JACOBIAN + 36].copy().reshape(6, 6)
        cell.C_robot = fs[sk.C_ROBOT : sk.C_ROBOT + 9].copy().reshape(3, 3)
        cell.C_total = cell.C_robot + cell.C_tool
        solver.force_scale = v[sk.FORCE_SCALE_NOW]
        cell.spindle_rpm = cell.scenario.spindle_rpm * v[sk.SPINDLE_SHARE]
        if self._thermal is not None:
            self._thermal.work_j = v[sk.WORK_J]
        if self._backlash is not None:  # the links moved the tool and the marker
            self._backlash.q_link[:3] = fs[sk.LINK_Q : sk.LINK_Q + 3]
            self._backlash.share = (
                fs[sk.LINK_TIP : sk.LINK_TIP + 3].copy(),
                fs[sk.LINK_MARKER : sk.LINK_MARKER + 3].copy(),
            )
            cell.geometry_offset_task_m = fs[sk.GEOMETRY_OFFSET : sk.GEOMETRY_OFFSET + 3].copy()
            cell.marker_offset_base_m = fs[sk.MARKER_OFFSET : sk.MARKER_OFFSET + 3].copy()
        if i[sk.FAILURE] and env.failure is None:
            env.failure = "force_limit"
        env.steps = i[sk.STEPS]
