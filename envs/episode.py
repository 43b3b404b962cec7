"""One simulated hole's episode: the cell and its physics, the two steppers, the recorder and what they show.

:class:`DrillEpisode` is the engine room of :class:`drillgym.envs.drill_env.UR5BoneDrillEnv` (the Gymnasium API:
arguments, ``reset``, ``step``, rendering): it builds the cell for a scenario, starts each episode in the env's
Python objects, advances it on the compiled step (:mod:`drillgym.envs.compiled_step`) or the Python one
(:mod:`drillgym.envs.python_step`), replays command sequences open loop, and reads the observation, the info and the
metrics. Units SI; frames as named (base, task, sensor).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np

from drillgym.envs import python_step
from drillgym.envs.cell import SimCell, draw_specimen_hardness
from drillgym.envs.cell_params import CellParams
from drillgym.envs.compiled_step import CompiledEpisode
from drillgym.envs.constants import ACTION_DIM, scale_action, scaled_rows
from drillgym.envs.drilling.bone import BonePreset
from drillgym.envs.effects.base import Effect, EffectStack
from drillgym.envs.metrics import episode_metrics
from drillgym.envs.plan import DrillPlan
from drillgym.envs.pybullet_world import PyBulletWorld
from drillgym.envs.read_through import ReadThrough
from drillgym.envs.reward import checked_action
from drillgym.envs.robot.ur5 import TRACKER_FRAME
from drillgym.envs.sample_record import SampleRecord, record_channels
from drillgym.envs.scenario import Scenario
from drillgym.envs.sensors import ForceTorqueSensor, PositionTracker
from drillgym.envs.task import DrillPath, Phase

CELLS_KEPT = 32
"""Cells (:class:`~drillgym.envs.cell.SimCell`) an env keeps for the scenarios it ran last: a reset that returns to
one of them reuses it instead of building it again (~0.3 ms, and ~20 ms for a new engagement table). A diagnosis
replays each of its episodes in turn, each with its own scenario and specimen hardness: 32 covers its usual 12-30."""


class DrillEpisode(ReadThrough):
    """The episode machinery of the sim env (the env's ``__init__`` sets the attributes declared here)."""

    scenario: Scenario
    cell_params: CellParams | None
    bone_material: BonePreset | None
    recorder: SampleRecord
    world: PyBulletWorld | None
    effects: EffectStack | None
    np_random: np.random.Generator
    use_compiled_step = True
    """Without unmodelled effects (or with only :attr:`Effect.compiled` ones), step with the compiled kernel (:mod:`drillgym.envs.step_kernel`) from the next
    ``reset``; False keeps the Python step (the same physics, equal to rounding: ``tests/envs/test_step_kernel.py``)."""

    def _init_episode(self, scenario: Scenario) -> None:
        """Build the cell for ``scenario`` and start an episode (the env's ``__init__``, after its arguments)."""
        self.recorder = SampleRecord()
        self.effects = None
        self._effects_attached = False
        self._cells: dict[Scenario, SimCell] = {}
        self._build(scenario)
        self._reset_state()

    def _build(self, scenario: Scenario) -> None:
        """(Re)build the cell, the path and the bone for ``scenario`` (the PyBullet client is kept)."""
        self.scenario = scenario
        cell = self._cells.pop(scenario, None)
        if cell is None:
            cell = SimCell(scenario, self.cell_params, self.bone_material)
        else:  # built for an earlier episode: as new once its effects are undone (reset does the rest)
            cell.clear_effects()
        self._effects_attached = False
        self._cells[scenario] = cell  # the most recently used last
        while len(self._cells) > CELLS_KEPT:
            del self._cells[next(iter(self._cells))]
        self.cell = cell
        self.path = DrillPath(scenario.depth_m, scenario.feed_m_s)
        self.max_time_s = 3.0 * self.path.nominal_duration_s()
        if self.world is not None:
            self.world.place_bone(self.cell.T_base_task, scenario.beta_rad)

    def _reset_state(self, specimen_seed: int | None = None) -> None:
        if self.effects is not None or self._effects_attached:  # first, as a new cell is: nothing of the last
            self.cell.clear_effects()  # episode's effects may reach the start pose, the marker or the RTDE TCP
        self.path.reset()
        self.cell.reset(np.array([0.0, 0.0, self.path.s_m]))
        rng = self.np_random
        hardness = draw_specimen_hardness(rng, self.scenario.bone_variability)  # drawn either way: same noise stream
        if specimen_seed is not None:
            hardness = draw_specimen_hardness(np.random.default_rng(specimen_seed), self.scenario.bone_variability)
        self.cell.set_specimen_hardness(hardness)
        self.ft = ForceTorqueSensor(self.scenario.ft_noise_n, rng)
        self.tracker = PositionTracker(self.scenario.tracker_noise_m, rng)
        self.t_s = 0.0
        self.correction_base_m = np.zeros(3)
        self.feed_scale = 1.0
        self.pending: deque[tuple[float, np.ndarray, float]] = deque()
        self.prev_action = np.zeros(ACTION_DIM)
        self.peak_lateral_n = 0.0
        self.step_deviation_m = 0.0
        """Mean true tip deviation over the last agent step's samples (m)."""
        self.step_lateral_n = 0.0
        """Mean true lateral force over the last agent step's samples (N)."""
        self.recorder.clear()
        self.ft_samples = np.zeros((2, 6))
        self.ft_last = np.zeros(6)
        self.ft_mean = np.zeros(6)
        self.failure: str | None = None
        self.metrics: dict[str, float] | None = None
        self.truncated = False
        self.steps = 0
        self.marker_start_base = self.cell.marker_base_m(self.cell.q_motor_rad)
        self.s_start_m = self.path.s_m
        self.tracker_stamp = -1.0
        self.tracker_reading = np.zeros(3)
        self.tracker_error_base = np.zeros(3)
        self.tracker_lateral_m = 0.0
        self.rtde_tcp_base = self.cell.tcp_rtde_base_m()
        self.step_terms: dict[str, float] = {}
        self._effects_attached = self.effects is not None
        if self.effects is not None:
            self.effects.attach(self)
        compiled = self.effects is None or self.effects.compiled
        self._kernel = CompiledEpisode(self) if compiled and self.use_compiled_step else None

    def set_effects(self, effects: list[Effect] | tuple[Effect, ...] | None) -> None:
        """Switch unmodelled effects (:mod:`drillgym.envs.effects`) on from the next ``reset``; None or [] switches them off."""
        self.effects = EffectStack(effects) if effects else None

    def advance(self, action: np.ndarray) -> tuple[bool, bool]:
        """:meth:`step`'s physics alone: ``(terminated, truncated)``, without observation, reward or info.

        For open-loop replays that read the recorder and the cell afterwards (the diagnosis): the
        physics, the recorded channels and the metrics are those of :meth:`step`; the reward's state
        (previous action, peak force) is left as it is.
        """
        return self._advance(checked_action(action, "env state unchanged"), "advance")

    def _advance(self, a: np.ndarray, caller: str) -> tuple[bool, bool]:
        """One agent step of physics for a checked action ``a``; sets ``step_deviation_m`` and ``step_lateral_n``."""
        if self._ended_already():
            raise RuntimeError(f"{caller}() called after the episode ended; call reset()")
        corr, scale = scale_action(a)
        kernel = self._kernel
        if kernel is not None:  # no effects, or only compiled ones (Effect.compiled): one compiled call
            kernel.step(corr, scale)
            return self._ended()
        return python_step.advance(self, corr, scale)

    def advance_open_loop(self, actions: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        """:meth:`advance` through ``actions`` (T, 4) until the episode ends (an open-loop replay).

        Returns the steps taken and, after each, the motor-side joint angles (T, 6, rad) and the tracker
        reading (T, 3, m, base frame); rows past the end are NaN. The physics and the records are those of
        calling :meth:`advance` step by step (equal within 1e-12, ``tests/envs/test_step_kernel.py``); on the
        compiled step without sensor noise the whole replay is one compiled call.
        """
        done, q, tracker, out = self._open_loop(actions, "advance_open_loop")
        if out is not None:
            self._record(out)
            self._ended()
        return done, q, tracker

    def replay_open_loop(self, actions: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """:meth:`advance_open_loop`, returning the recorder's channels as arrays instead of keeping them.

        The fourth item holds every channel of :class:`~drillgym.envs.metrics.EpisodeRecorder` (one row per
        F/T sample; ``tip_task_m``, ``ft_force_n`` and ``ft_torque_nm`` (n, 3)), with the values the recorder
        would hold. On the compiled step without sensor noise nothing is appended to the recorder and no
        metrics are computed (a diagnosis replays thousands of episodes and reads each once); otherwise the
        episode is recorded as by :meth:`advance_open_loop` and its channels are read from the recorder.
        """
        done, q, tracker, out = self._open_loop(actions, "replay_open_loop")
        if out is not None:
            assert self._kernel is not None
            self.truncated = self._kernel.v.truncated
            return done, q, tracker, record_channels(out)
        return done, q, tracker, self.recorder.channels()

    def _open_loop(self, actions: np.ndarray, caller: str) -> tuple[int, np.ndarray, np.ndarray, np.ndarray | None]:
        """Advance through ``actions``, in one compiled call or step by step.

        In one compiled call where the episode is noiseless and compiled (its sample rows are returned, not
        recorded); else step by step (recorded; rows None).
        """
        a = checked_action(actions, "env state unchanged", num_envs=len(actions))
        if self._ended_already():
            raise RuntimeError(f"{caller}() called after the episode ended; call reset()")
        kernel = self._kernel
        if kernel is not None and kernel.noiseless:
            return kernel.open_loop(scaled_rows(a))
        q = np.full((len(a), 6), np.nan)
        tracker = np.full((len(a), 3), np.nan)
        done = 0
        for k, row in enumerate(a):
            terminated, truncated = self._advance(row, caller)
            q[k], tracker[k] = self.cell.q_motor_rad, self.tracker_reading
            done = k + 1
            if terminated or truncated:
                break
        return done, q, tracker, None

    def _ended_already(self) -> bool:
        """Whether the episode ended at an earlier step (drilled and retracted, or the force limit)."""
        if self._kernel is not None and self._kernel.started:
            return self._kernel.ended
        return self.path.phase == Phase.DONE or self.failure is not None

    def _record(self, rows: np.ndarray) -> None:
        """Append sample rows of the compiled step's layout to the recorder."""
        self.recorder.extend(len(rows))[:] = rows

    def _ended(self) -> tuple[bool, bool]:
        """``(terminated, truncated)`` after a compiled step; the metrics when the episode ended."""
        assert self._kernel is not None
        terminated, truncated = self._kernel.v.terminated, self._kernel.v.truncated
        self.truncated = truncated
        if terminated or truncated:
            self.metrics = self.episode_metrics()
        return terminated, truncated

    def _observation(self) -> dict[str, np.ndarray]:
        if self._kernel is not None and self._kernel.started:
            return self._kernel.observation()
        return python_step.observation(self)

    def _info(self) -> dict[str, Any]:
        if self._kernel is not None and self._kernel.started:
            return self._kernel.info()
        return python_step.info(self)

    @property
    def specimen_hardness(self) -> float:
        """This episode's specimen hardness factor (privileged; drawn at ``reset``, :func:`drillgym.envs.cell.draw_specimen_hardness`)."""
        return self.cell.specimen_hardness

    @property
    def plan(self) -> DrillPlan:
        """The surgical plan of this scenario (what a controller may know before drilling)."""
        return DrillPlan.from_scenario(self.scenario, self.cell.T_base_task, self.cell.tcp_offset_m)

    def episode_metrics(self) -> dict[str, float]:
        """Metrics of the episode so far (see :mod:`drillgym.envs.metrics`)."""
        centre = self.cell.hole.centre_at(self.scenario.entry_depth_m)
        offset = math.hypot(centre[0], centre[1]) if centre is not None else float("nan")
        return episode_metrics(self.recorder, self.scenario.entry_depth_m, self.scenario.depth_m, offset)

    def tracker_marker_pose_base(self) -> np.ndarray:
        """True ``T_base_marker`` (privileged; for tests and diagnostics)."""
        return self.cell.kin.fk(self.cell.q_actual_rad(), TRACKER_FRAME)
