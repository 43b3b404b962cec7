"""The compiled step's arrays (:mod:`drillgym.envs.step_kernel`) for the env's state, and back.

The single env keeps its state in Python objects (the cell, the path, the tip balance, the queue of
commands), which unmodelled effects and the rest of the project read and change. Without effects, or
with only compiled ones (:attr:`Effect.compiled <drillgym.envs.effects.base.Effect.compiled>`; their
each writes its parameters into the episode's ``params``: :meth:`Effect.set_kernel_params`), its step runs
:func:`~drillgym.envs.step_kernel.advance_batch` on one episode's named state (:mod:`drillgym.envs.episode_state`):
:class:`KernelState` copies the state in (:meth:`~KernelState.load`), the kernel advances it, and
:meth:`~KernelState.store` copies it back, so every reader sees what the Python step would have left. The batched env builds the same arrays for N
episodes (:mod:`drillgym.envs.batched`) from each episode's :class:`KernelState`, and shares :func:`is_noisy`
and :func:`record_channels` with it.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs import step_kernel as sk
from drillgym.envs.cell import SimCell, chains_of
from drillgym.envs.constants import PHYSICS_DT_S, SUBSTEPS_PER_STEP, TRACKER_RATE_HZ
from drillgym.envs.drilling.contact import ContactSample
from drillgym.envs.drilling.force_model import EngagementTable
from drillgym.envs.episode_state import STATE_FIELDS, STATE_SCALARS, StateScalars, new_params, new_state
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
    p: np.void,
    cell: SimCell,
    latency_s: float,
    force_limit_n: float,
    max_time_s: float,
    marker_start_base_m: np.ndarray,
    s_start_m: float,
    ft_noise_std: np.ndarray,
    tracker_noise_m: float,
) -> None:
    """Write an episode's constant parameters (a :data:`~drillgym.envs.episode_state.PARAMS` record) for the cell as it is now."""
    sc, solver, geo = cell.scenario, cell.solver, cell.geometry
    p["latency_s"] = latency_s
    p["servo_gain"] = cell.servo_gain
    p["tan_beta"] = solver.tan_beta
    p["k_lat_n"] = solver.k_lat_n
    p["guidance_exponent"] = solver.guidance_exponent
    p["wall_floor"] = solver.wall_floor
    p["wall_length_m"] = solver.wall_length_m
    p["force_scale"] = solver.force_scale
    p["tracker_noise_m"] = tracker_noise_m
    p["force_limit_n"] = force_limit_n
    p["sensor_arm_m"] = cell.sensor_arm_m
    p["depth_m"] = sc.depth_m
    p["feed_m_s"] = sc.feed_m_s
    p["max_time_s"] = max_time_s
    p["n_lips"] = geo.n_lips
    p["rev_per_s"] = sc.spindle_rpm / 60.0
    p["sin_kappa"] = math.sin(geo.kappa_rad)
    p["R_base_task"] = cell.R_base_task
    p["entry_base_m"] = cell.entry_base_m
    p["C_tool"] = cell.C_tool
    p["stiffness_nm_rad"] = cell.joints.stiffness_nm_rad
    p["marker_start_base_m"] = marker_start_base_m
    p["s_start_m"] = s_start_m
    p["stage_bounds_m"] = solver._bounds
    p["ft_std"] = ft_noise_std
    p["n_grid"] = solver.grid.shape[0]
    p["n_bins"] = cell.hole.filled.shape[0]
    p["bin_m"] = cell.hole.bin_m
    p["omega_rad_s"] = 2.0 * math.pi * sc.spindle_rpm / 60.0
    if cell.geometry_offset_task_m is not None:  # the offsets themselves are state (``load``)
        p["geometry_on"] = p["target_offset_on"] = True
    if cell.marker_offset_base_m is not None:
        p["marker_on"] = True
    p["entry_guidance"] = solver.entry_guidance


def tracker_sample_is_new(t_s: Any, stamp_s: Any) -> Any:
    """Whether the step starting at ``t_s`` ends with a new tracker sample (the last one was at ``stamp_s``).

    Floats or arrays of them (one per episode); the end time is the kernel's sum, term by term.
    """
    for _ in range(SUBSTEPS_PER_STEP):
        t_s = t_s + PHYSICS_DT_S
    return np.floor(t_s * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ != stamp_s  # sensors.latest_sample_time_s


def draw_noise(
    rng: np.random.Generator, noise: np.ndarray, ft_noisy: bool, tracker_noisy: bool, tracker_new: bool
) -> None:
    """The step's standard normals into ``noise`` from the episode's generator, in the Python step's order.

    The F/T's (5x6) if it is noisy, then the tracker's (3) if it is noisy and its sample is new, one after the
    other from ``noise[0]`` on, as the compiled step reads them from ``noise_at`` = 0.
    """
    at = 0
    if ft_noisy:
        at = 6 * SUBSTEPS_PER_STEP
        rng.standard_normal(out=noise[:at])
    if tracker_noisy and tracker_new:
        rng.standard_normal(out=noise[at : at + 3])


def noisy_sensors(p: np.void) -> tuple[bool, bool]:
    """Whether an episode's F/T and its tracker are noisy (its step reads normals for them: :func:`draw_noise`)."""
    return bool(p["ft_std"][0] > 0), bool(p["tracker_noise_m"] > 0)


def is_noisy(p: np.void) -> bool:
    """Whether an episode's step reads any normals."""
    return any(noisy_sensors(p))


PHASES = tuple(Phase)
"""The path phases by code."""


class KernelState:
    """The compiled step's arrays for one env's episode (N = 1; built at ``reset``, without effects or with compiled ones).

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
        self.arrays = sk.KernelArrays(
            state=new_state(1),
            params=new_params(1),
            pend=np.zeros((1, sk.PENDING_ROWS, 5)),
            tab=table_rows(cell.table, cell.solver.depth_profile)[None],
            rows=np.empty((1, cell.solver.grid.shape[0], 4)),
            chains=np.stack(chains_of(cell.kin))[None],
            centre=hole.centre_xy_m[None],
            filled=hole.filled[None],
            bins=hole.bins[None],
            delay=np.zeros((1, sk.DELAY_ROWS, 4)),
        )
        self.state, self.params, self.pend = self.arrays.state, self.arrays.params, self.arrays.pend[0]
        self.s, self.p = self.state[0], self.params[0]
        self._scalars = self.state.view(STATE_SCALARS)
        episode_params(
            self.p,
            cell,
            env.scenario.latency_s,
            env.scenario.force_limit_n,
            env.max_time_s,
            env.marker_start_base,
            env.s_start_m,
            env.ft._noise_std,
            env.tracker.noise_m,
        )
        effects = [] if env.effects is None else env.effects.effects
        if env.effects is not None and not env.effects.compiled:
            raise ValueError(f"the compiled step does not run all of {effects!r}; step this env in Python")
        for e in effects:
            e.set_kernel_params(self.p)
        self.effects = effects
        self._moves_links = self.p["backlash_half_rad"] > 0.0  # joint backlash moves the tool and the marker
        self.noise = np.zeros((1, NOISE_SIZE))
        self.command = np.zeros((1, 4))
        self.active = np.ones(1, dtype=bool)
        self.loaded = False
        self._noisy = noisy_sensors(self.p)
        self._noise_at, self._singular = self.state["noise_at"], self.state["singular"]
        self._arr = {f.name: self.state[f.name][0] for f in STATE_FIELDS if f.shape}
        """Episode 0's array fields as plain array views (faster to read than the record's fields)."""

    def step(self, env: UR5BoneDrillEnv, correction_base_m: np.ndarray, feed_scale: float) -> None:
        """Advance ``env`` by one agent step of ``command``; its sample rows go to the env's record."""
        if not self.loaded:
            self.load(env)
        t_apply = env.t_s + env.scenario.latency_s  # as the kernel queues it
        cmd = self.command
        cmd[0, :3] = correction_base_m
        cmd[0, 3] = feed_scale
        draw_noise(env.np_random, self.noise[0], *self._noisy, tracker_sample_is_new(env.t_s, env.tracker_stamp))
        self._noise_at[0] = 0
        record = env.recorder
        record.reserve(SUBSTEPS_PER_STEP)
        sk.advance_batch(*self.arrays, cmd, self.noise, record.buffer, record.count, self.active)
        if self._singular[0]:
            raise np.linalg.LinAlgError(f"singular TCP Jacobian at q = {env.cell.q_motor_rad.tolist()} rad")
        env.pending.append((t_apply, correction_base_m, feed_scale))
        self.store(env)

    @property
    def noiseless(self) -> bool:
        """Whether the episode's F/T and tracker have no noise (a step then draws nothing)."""
        return not (self.p["ft_std"] > 0.0).any() and not self.p["tracker_noise_m"] > 0.0

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
        s = self.s
        if s["singular"]:
            raise np.linalg.LinAlgError(f"singular TCP Jacobian at q = {s['q_motor_rad'].tolist()} rad")
        pend = self.pend
        env.pending.clear()
        for k in range(int(s["pending"])):  # the queue as the kernel left it: every command applied was popped
            env.pending.append((float(pend[k, 0]), pend[k, 1:4].copy(), float(pend[k, 4])))
        env.correction_base_m = s["correction_base_m"].copy()
        self.store(env)
        return done, q, tracker, out[: SUBSTEPS_PER_STEP * done]

    @property
    def terminated(self) -> bool:
        """Whether the episode ended at the last step."""
        return bool(self.s["terminated"])

    @property
    def truncated(self) -> bool:
        """Whether the episode hit its time or step limit at the last step."""
        return bool(self.s["truncated"])

    def load(self, env: UR5BoneDrillEnv) -> None:
        """Copy the env's state into the arrays (at the episode's first step)."""
        s, p, cell, solver = self.s, self.p, env.cell, env.cell.solver
        s["t_s"] = env.t_s
        s["path_m"] = env.path.s_m
        s["feed_scale"] = env.feed_scale
        s["correction_base_m"] = env.correction_base_m
        s["tip_balance"] = [*solver.rigid, *solver.tip, solver.bottom_z, solver.depth_local]
        s["rtde_tcp_base_m"] = env.rtde_tcp_base
        s["tracker_stamp_s"] = env.tracker_stamp
        s["tracker_reading_base_m"] = env.tracker_reading
        s["q_motor_rad"] = cell.q_motor_rad
        s["jacobian"] = cell.J_tcp
        s["c_robot_m_n"] = cell.C_robot
        p["force_scale"] = solver.force_scale
        s["force_scale_now"] = solver.force_scale
        s["spindle_share"] = cell.spindle_rpm / cell.scenario.spindle_rpm
        if cell.geometry_offset_task_m is not None:
            s["geometry_offset_task_m"] = cell.geometry_offset_task_m
        if cell.marker_offset_base_m is not None:
            s["marker_offset_base_m"] = cell.marker_offset_base_m
        s["target_offset_task_m"] = s["geometry_offset_task_m"]
        for e in self.effects:
            e.load_kernel_state(s)
        smp = cell.sample
        s["sample"] = [
            *smp.tip,
            *smp.rigid,
            *smp.force,
            smp.torque_axis,
            smp.depth_local,
            smp.stage,
            1.0 if smp.cutting else 0.0,
        ]
        s["phase"] = int(env.path.phase)
        s["touching"] = solver.touching
        s["bracket"] = solver._j
        s["failure"] = env.failure is not None
        s["steps"] = env.steps
        s["pending"] = len(env.pending)
        for k, (t_apply, corr, scale) in enumerate(env.pending):
            self.pend[k, 0] = t_apply
            self.pend[k, 1:4] = corr
            self.pend[k, 4] = scale
        self.loaded = True

    def store(self, env: UR5BoneDrillEnv) -> None:
        """Copy the arrays back into the env's state (its queue has the step's command appended already)."""
        cell, solver = env.cell, env.cell.solver
        v = StateScalars._make(self._scalars[0].item())  # Python numbers
        a = self._arr
        env.t_s = v.t_s
        env.path.s_m = v.path_m
        env.path.phase = PHASES[v.phase]
        env.feed_scale = v.feed_scale
        pending = env.pending
        for _ in range(len(pending) - v.pending):  # the commands applied: the last one is in effect
            env.correction_base_m = pending.popleft()[1]
        tb = a["tip_balance"].tolist()
        solver.rigid, solver.tip = tb[0:3], tb[3:6]
        solver.bottom_z, solver.depth_local = tb[6], tb[7]
        solver.touching, solver._j = v.touching, v.bracket
        smp = a["sample"].tolist()
        solver.force, solver.torque = smp[6:9], smp[9]
        cell.sample = ContactSample(
            (smp[0], smp[1], smp[2]),
            (smp[3], smp[4], smp[5]),
            (smp[6], smp[7], smp[8]),
            smp[9],
            smp[10],
            int(smp[11]),
            smp[12] == 1.0,
        )
        env.rtde_tcp_base = a["rtde_tcp_base_m"].copy()
        env.ft_last = a["ft_last"].copy()
        env.ft_mean = a["ft_mean"].copy()
        env.tracker_stamp = v.tracker_stamp_s
        env.tracker_reading = a["tracker_reading_base_m"].copy()
        env.tracker_error_base = a["tracker_error_base_m"].copy()
        env.tracker_lateral_m = v.tracker_lateral_m
        env.step_deviation_m = v.step_deviation_m
        env.step_lateral_n = v.step_lateral_n
        cell.q_motor_rad = a["q_motor_rad"].copy()
        cell.J_tcp = a["jacobian"].copy()
        cell.C_robot = a["c_robot_m_n"].copy()
        cell.C_total = cell.C_robot + cell.C_tool
        solver.force_scale = v.force_scale_now
        cell.spindle_rpm = cell.scenario.spindle_rpm * v.spindle_share
        for e in self.effects:
            e.store_kernel_state(self.s)
        if self._moves_links:  # the links moved the tool and the marker
            cell.geometry_offset_task_m = a["geometry_offset_task_m"].copy()
            cell.marker_offset_base_m = a["marker_offset_base_m"].copy()
        if v.failure and env.failure is None:
            env.failure = "force_limit"
        env.steps = v.steps
