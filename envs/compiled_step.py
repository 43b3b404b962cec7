"""The single env's episode on the compiled step: the named state is the truth, the env's objects read it.

Without unmodelled effects, or with only compiled ones (:attr:`Effect.compiled
<drillgym.envs.effects.base.Effect.compiled>`), the env's step is one call of
:func:`~drillgym.envs.step_kernel.advance_batch` on an episode batch of one: the episode's records
(:mod:`drillgym.envs.episode_state`) start from what ``reset`` built (:mod:`drillgym.envs.episode_start`) and the
kernel advances them, appending its sample rows to the env's record (:mod:`drillgym.envs.sample_record`). The
observation, the info and the reward's inputs are read from the state (:meth:`CompiledEpisode.observation`,
:meth:`~CompiledEpisode.info`), as the batched env reads its N episodes'. The env's objects (the env's episode
fields, its path, the cell and its tip balance) read their mutable fields from the state when someone asks
(:mod:`drillgym.envs.read_through`), so a step copies nothing back. Code that changes those objects between steps
must step in Python (``UR5BoneDrillEnv.use_compiled_step = False``).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from drillgym.envs import step_kernel as sk
from drillgym.envs.cell import chains_of
from drillgym.envs.constants import SUBSTEPS_PER_STEP
from drillgym.envs.drilling.contact import ContactSample
from drillgym.envs.episode_start import episode_params, start_state, table_rows
from drillgym.envs.episode_state import (
    STATE_FIELDS,
    STATE_SCALARS,
    STEP_SCALARS,
    StateScalars,
    StepScalars,
    new_params,
    new_state,
)
from drillgym.envs.read_through import Reader, ReadThrough, attach, detach, forget
from drillgym.envs.sample_record import OUT_COLUMNS
from drillgym.envs.step_noise import NOISE_SIZE, draw_noise, noisy_sensors, tracker_sample_is_new
from drillgym.envs.task import Phase
from drillgym.envs.views import observation_from_state

PHASES = tuple(Phase)
"""The path phases by code."""


def check_compiled(env: Any) -> None:
    """``ValueError`` unless the compiled step runs ``env``'s episode (no guidance hook, only compiled effects)."""
    if env.cell.solver.guidance_hook is not None:
        raise ValueError("the compiled step has no guidance hook; step this env in Python")
    if env.effects is not None and not env.effects.compiled:
        raise ValueError(f"the compiled step does not run all of {env.effects.effects!r}; step this env in Python")


def episode_arrays(env: Any) -> sk.KernelArrays:
    """The compiled step's arrays for ``env``'s episode as ``reset`` left it (N = 1; the cell's hole is shared)."""
    check_compiled(env)
    cell = env.cell
    hole = cell.hole
    arrays = sk.KernelArrays(
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
    episode_params(arrays.params[0], env)
    start_state(arrays.state[0], arrays.pend[0], env)
    return arrays


class CompiledEpisode:
    """One env's episode on the compiled step, from its first step (built at ``reset``, started at the first step).

    Until :meth:`release` (the next ``reset``), the env, its path, its cell and the cell's tip balance read their
    mutable fields from the state (:mod:`drillgym.envs.read_through`).
    """

    def __init__(self, env: Any) -> None:
        check_compiled(env)
        self.env = env
        self.effects = [] if env.effects is None else env.effects.effects
        self.started = False
        self.noise = np.zeros((1, NOISE_SIZE))
        self.command = np.zeros((1, 4))
        self.active = np.ones(1, dtype=bool)
        self._tracking = np.zeros(1, dtype=bool)
        self._reattach = False
        self.v: Any = None
        """The scalars a step reads back, after the last step, as Python numbers (:data:`StepScalars`)."""

    def start(self) -> None:
        """Build the records from the env's objects and let those read their fields from the state."""
        self.arrays = episode_arrays(self.env)
        self._views()
        self._noisy = noisy_sensors(self.p)
        self._c_tool = self.env.cell.C_tool
        self._moves_links = bool(self.p["backlash_half_rad"] > 0.0)  # joint backlash moves the tool and the marker
        self.v = StepScalars._make(self._step_scalars[0].item())
        self.started = True
        self._attach()

    def _views(self) -> None:
        """The record views the step reads (rebuilt after a copy: a pickled view is an array of its own)."""
        self.state, self.pend = self.arrays.state, self.arrays.pend[0]
        self.s, self.p = self.state[0], self.arrays.params[0]
        self._scalars = self.state.view(STATE_SCALARS)
        self._step_scalars = self.state.view(STEP_SCALARS)
        self._noise_at = self.state["noise_at"]
        self._arr = {f.name: self.state[f.name][0] for f in STATE_FIELDS if f.shape}
        """Episode 0's array fields as plain array views (faster to read than the record's fields)."""

    def _attach(self) -> None:
        """Let the env's objects read their fields from the state."""
        env = self.env
        self._objects: tuple[tuple[ReadThrough, Reader], ...] = (
            (env, self._reading(self._env_fields)),
            (env.path, self._reading(self._path_fields)),
            (env.cell, self._reading(self._cell_fields)),
            (env.cell.solver, self._reading(self._solver_fields)),
        )
        self._read = False
        for obj, reader in self._objects:
            attach(obj, reader)

    def release(self) -> None:
        """Put every field back into the env's objects (before the next ``reset`` changes them)."""
        if self.started and not self._reattach:  # (a restored copy's objects hold their fields already)
            for obj, _ in self._objects:
                detach(obj)
        self.started = self._reattach = False

    def __getstate__(self) -> dict[str, Any]:
        """The arrays and the scalars; not the views of them nor the objects' readers (rebuilt on restore)."""
        derived = {"state", "pend", "s", "p", "_scalars", "_step_scalars", "_noise_at", "_arr", "_objects"}
        return {k: v for k, v in self.__dict__.items() if k not in derived}

    def __setstate__(self, state: dict[str, Any]) -> None:
        """Restore a copy: its views of its own arrays, and its objects read through once it steps again."""
        self.__dict__.update(state)
        if self.started:
            self._views()
            self._reattach = True  # the copied objects hold a snapshot of the state until then

    def _ready(self) -> None:
        """Before a step: start the episode, or let a restored copy's objects read through again."""
        if not self.started:
            self.start()
        elif self._reattach:
            self._restored()

    def _restored(self) -> None:
        """A restored copy's first step: the kernel cuts its own cell's hole again, and the objects read through."""
        hole = self.env.cell.hole  # the copy's hole holds what the arrays held when copied
        self.arrays = self.arrays._replace(
            centre=hole.centre_xy_m[None], filled=hole.filled[None], bins=hole.bins[None]
        )
        self._reattach = False
        self._attach()

    # ------------------------------------------------------------------ stepping
    def step(self, correction_base_m: np.ndarray, feed_scale: float) -> None:
        """Advance the episode by one agent step of the command; its sample rows go to the env's record."""
        self._ready()
        env, v = self.env, self.v
        cmd = self.command
        cmd[0, :3] = correction_base_m
        cmd[0, 3] = feed_scale
        draw_noise(env.np_random, self.noise[0], *self._noisy, tracker_sample_is_new(v.t_s, v.tracker_stamp_s))
        self._noise_at[0] = 0
        record = env.recorder
        record.reserve(SUBSTEPS_PER_STEP)
        sk.advance_batch(*self.arrays, cmd, self.noise, record.buffer, record.count, self.active)
        self._stepped()

    def open_loop(self, commands: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, np.ndarray]:
        """Advance through ``commands`` (T, 4: correction m base frame, feed scale) in one call, without noise.

        Returns the steps taken, the motor angles (T, 6) and tracker readings (T, 3) after each step (NaN past the
        end) and the steps' sample rows (5 per step, ``OUT_COLUMNS``).
        """
        if not self.noiseless:
            raise ValueError("an open-loop call draws no noise: the episode's sensors must be noiseless")
        self._ready()
        n = len(commands)
        out = np.empty((SUBSTEPS_PER_STEP * n, OUT_COLUMNS))
        q = np.full((n, 6), math.nan)
        tracker = np.full((n, 3), math.nan)
        done = sk.advance_open_loop(*self.arrays, np.ascontiguousarray(commands, dtype=float), out, q, tracker)
        self._stepped()
        return done, q, tracker, out[: SUBSTEPS_PER_STEP * done]

    def _stepped(self) -> None:
        """After the kernel ran: the scalars, the effects' Python state, and the objects' fields read afresh."""
        self.v = v = StepScalars._make(self._step_scalars[0].item())
        if v.singular:
            raise np.linalg.LinAlgError(f"singular TCP Jacobian at q = {self._arr['q_motor_rad'].tolist()} rad")
        for e in self.effects:
            e.store_kernel_state(self.s)
        if self._read:  # someone read the objects' fields since the last step: they are stale now
            for obj, _ in self._objects:
                forget(obj)
            self._read = False

    @property
    def noiseless(self) -> bool:
        """Whether the episode's F/T and tracker have no noise (a step then draws nothing)."""
        env = self.env
        return not (env.ft._noise_std > 0.0).any() and not env.tracker.noise_m > 0.0

    @property
    def ended(self) -> bool:
        """Whether the episode is over: drilled and retracted, or stopped by the force limit."""
        v = self.v
        return self.started and (v.phase == Phase.DONE or v.failure)

    # ------------------------------------------------------------------ what the state shows
    def observation(self) -> dict[str, np.ndarray]:
        """The observation (:func:`drillgym.envs.views.observation_from_state` for this one episode)."""
        env = self.env
        self._tracking[0] = len(env.recorder) > 0
        return observation_from_state(self.state, self.arrays.params, self._tracking, env.scenario.tracker, None)

    def info(self) -> dict[str, Any]:
        """The step's info: the privileged state (true tip, force, stage), the reward's terms and the failure."""
        env, v, a = self.env, self.v, self._arr
        row = a["sample"]
        smp = row.tolist()
        force = row[6:9].copy()
        info: dict[str, Any] = {
            "t_s": v.t_s,
            "phase": v.phase,
            "stage": int(smp[11]),
            "depth_cmd_m": v.path_m,
            "tip_pos_task_m": row[0:3].copy(),
            "deviation_m": math.hypot(smp[0], smp[1]),
            "tip_deflection_robot_m": a["c_robot_m_n"] @ force,
            "tip_deflection_tool_m": self._c_tool @ force,
            "force_true_n": force.copy(),
            "depth_local_m": smp[10],
            "reward_terms": dict(env.step_terms),
            "failure": "force_limit" if v.failure else None,
            "specimen_hardness": env.specimen_hardness,
        }
        if env.metrics is not None:
            info["metrics"] = dict(env.metrics)
            info["metrics_truncated"] = env.truncated
        return info

    # ------------------------------------------------------------------ the objects' fields
    def _reading(self, fields: Reader) -> Reader:
        """``fields``, noting that the objects now hold fields read from this step's state."""

        def read() -> dict[str, Any]:
            self._read = True
            return fields()

        return read

    def _scalars_now(self) -> Any:
        """Every scalar of the state, as Python numbers (:data:`StateScalars`)."""
        return StateScalars._make(self._scalars[0].item())

    def _env_fields(self) -> dict[str, Any]:
        v, a, pend = self._scalars_now(), self._arr, self.pend
        return {
            "t_s": v.t_s,
            "feed_scale": v.feed_scale,
            "correction_base_m": a["correction_base_m"].copy(),
            "pending": deque((float(pend[k, 0]), pend[k, 1:4].copy(), float(pend[k, 4])) for k in range(v.pending)),
            "rtde_tcp_base": a["rtde_tcp_base_m"].copy(),
            "ft_last": a["ft_last"].copy(),
            "ft_mean": a["ft_mean"].copy(),
            "tracker_stamp": v.tracker_stamp_s,
            "tracker_reading": a["tracker_reading_base_m"].copy(),
            "tracker_error_base": a["tracker_error_base_m"].copy(),
            "tracker_lateral_m": v.tracker_lateral_m,
            "step_deviation_m": v.step_deviation_m,
            "step_lateral_n": v.step_lateral_n,
            "failure": "force_limit" if v.failure else None,
            "steps": v.steps,
        }

    def _path_fields(self) -> dict[str, Any]:
        return {"s_m": self.v.path_m, "phase": PHASES[self.v.phase]}

    def _solver_fields(self) -> dict[str, Any]:
        v, a = self._scalars_now(), self._arr
        tb = a["tip_balance"].tolist()
        smp = a["sample"].tolist()
        return {
            "rigid": tb[0:3],
            "tip": tb[3:6],
            "bottom_z": tb[6],
            "depth_local": tb[7],
            "touching": v.touching,
            "_j": v.bracket,
            "force": smp[6:9],
            "torque": smp[9],
            "force_scale": v.force_scale_now,
        }

    def _cell_fields(self) -> dict[str, Any]:
        cell, v, a = self.env.cell, self._scalars_now(), self._arr
        smp = a["sample"].tolist()
        c_robot = a["c_robot_m_n"].copy()
        fields = {
            "sample": ContactSample(
                (smp[0], smp[1], smp[2]),
                (smp[3], smp[4], smp[5]),
                (smp[6], smp[7], smp[8]),
                smp[9],
                smp[10],
                int(smp[11]),
                smp[12] == 1.0,
            ),
            "q_motor_rad": a["q_motor_rad"].copy(),
            "J_tcp": a["jacobian"].copy(),
            "C_robot": c_robot,
            "C_total": c_robot + cell.C_tool,
            "spindle_rpm": cell.scenario.spindle_rpm * v.spindle_share,
        }
        if self._moves_links:  # the links moved the tool and the marker
            fields["geometry_offset_task_m"] = a["geometry_offset_task_m"].copy()
            fields["marker_offset_base_m"] = a["marker_offset_base_m"].copy()
        return fields
