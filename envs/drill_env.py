"""Gymnasium environment: a UR5 drilling an inclined bone surface (Li et al. 2023's experiment)."""

from __future__ import annotations

import difflib
import math
from collections import deque
from dataclasses import fields
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.envs.cell import SimCell, draw_specimen_hardness
from drillgym.envs.cell_params import CellParams
from drillgym.envs.compiled_step import CompiledEpisode
from drillgym.envs.constants import (
    ACTION_DIM,
    CONTROL_DT_S,
    MAX_EPISODE_STEPS,
    PHYSICS_DT_S,
    RTDE_RATE_HZ,
    SUBSTEPS_PER_STEP,
    TRACKER_RATE_HZ,
    scale_action,
    scaled_rows,
)
from drillgym.envs.drilling.bone import BonePreset
from drillgym.envs.drilling.contact import SampleRow
from drillgym.envs.effects.base import Effect, EffectStack
from drillgym.envs.errors import UserError
from drillgym.envs.metrics import episode_metrics
from drillgym.envs.observation import observation_of, observation_space
from drillgym.envs.plan import DrillPlan
from drillgym.envs.pybullet_world import PyBulletWorld
from drillgym.envs.read_through import ReadThrough
from drillgym.envs.reward import RewardWeights, checked_action
from drillgym.envs.robot.ur5 import TRACKER_FRAME
from drillgym.envs.sample_record import (
    OUT_CUTTING,
    OUT_DEPTH_CMD,
    OUT_DEVIATION,
    OUT_FORCE,
    OUT_PHASE,
    OUT_STAGE,
    OUT_T_S,
    OUT_TIP,
    OUT_TORQUE,
    OUT_TRACKER_DEVIATION,
    SampleRecord,
    record_channels,
)
from drillgym.envs.scenario import Scenario
from drillgym.envs.sensors import ForceTorqueSensor, PositionTracker, latest_sample_time_s
from drillgym.envs.task import DrillPath, Phase

RESET_OPTIONS = frozenset({"scenario", "effects", "specimen_seed"})
"""Keys ``reset(options=...)`` accepts."""
CELLS_KEPT = 32
"""Cells (:class:`~drillgym.envs.cell.SimCell`) an env keeps for the scenarios it ran last: a reset that returns to
one of them reuses it instead of building it again (~0.3 ms, and ~20 ms for a new engagement table). A diagnosis
replays each of its episodes in turn, each with its own scenario and specimen hardness: 32 covers its usual 12-30."""


ENV_ARGUMENTS = (
    "render_mode",
    "cell_params",
    "bone_material",
    "reward_deviation_weight",
    "reward_force_weight",
    "reward_smooth_weight",
    "reward_peak_force_weight",
    "render_width_px",
    "render_height_px",
    "pybullet_world",
)
"""The env's own keyword arguments, beside the scenario's (:class:`drillgym.envs.scenario.Scenario`)."""


def _check_arguments(scenario_kwargs: dict[str, Any]) -> None:
    """``TypeError`` naming every accepted argument and the closest one for each unknown name."""
    known = sorted([*ENV_ARGUMENTS, *(f.name for f in fields(Scenario))])
    unknown = sorted(set(scenario_kwargs) - set(known))
    if not unknown:
        return
    hints = []
    for name in unknown:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hints.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    raise TypeError(f"unknown argument(s) {', '.join(hints)}; accepted: {', '.join(known)}")


def _max_norm_exceeds(forces_n: np.ndarray, limit_n: float) -> bool:
    """Whether any row's Euclidean norm exceeds ``limit_n``: ``max(norm(rows)) > limit`` exactly, cheaply.

    The norm is computed (as ``np.linalg.norm(..., axis=1)``) only when the rows' largest component is
    within a factor √3 (rounded up) of the limit; below that no row can exceed it.
    """
    if float(np.abs(forces_n).max()) * 1.7320508075688774 * (1.0 + 1e-12) <= limit_n:
        return False
    return float(np.max(np.linalg.norm(forces_n, axis=1))) > limit_n


class UR5BoneDrillEnv(ReadThrough, gym.Env[dict[str, np.ndarray], np.ndarray]):
    """A UR5 with compliant joints drilling an inclined bone surface: Li et al. 2023's experiment.

    ## Description

    A UR5 (CB3) with compliant joints holds a spindle with a straight twist drill and drills a bone
    specimen whose surface is inclined at the interaction angle β to the drill axis, as in Li et al.
    2023. The inclined entry loads the lips unequally (Li's four stages), the unbalanced force bends
    the drill and the arm, the tip skids downhill, and once the drill is inside, the hole wall guides
    it, so an early deviation is locked in. A compensator corrects the drill-tip target so the tip
    stays on the planned axis. Physics: quasi-static (see ``docs/physics.md``); world and rendering:
    PyBullet DIRECT.

    Frames. ``base``: the UR controller's base frame. ``task``: origin at the planned entry point on
    the bone surface, z along the planned drill axis into the bone, x in the plane of inclination
    pointing uphill (where the surface meets the drill first), y = z × x. With the default cell
    layout x_task = +y_base, y_task = +x_base, z_task = −z_base. ``sensor``: the F/T sensor, axes of
    the task frame at the nominal pose (z along the drill toward the bone).

    ## Action Space

    ``Box(-1, 1, (4,), float32)``; scaling in :mod:`drillgym.envs.constants`.

    | Num | Quantity | Min | Max | Frame | Unit |
    |-----|----------|-----|-----|-------|------|
    | 0-2 | drill-tip target correction, relative to the nominal path | -2e-3 | 2e-3 | base | m (after × ``MAX_CORRECTION_M``) |
    | 3 | feed-rate override, scale = 2**(2 a) | 0.25 | 4 | - | × nominal feed |

    The correction is absolute (not incremental) and takes effect ``latency_s`` after the step.
    Out-of-range actions are clipped to [-1, 1]; a NaN or infinite action raises ``ValueError`` and the
    env state is unchanged.

    ## Observation Space

    ``Dict`` of float32 Boxes, only what the real cell measures:

    | Key | Quantity | Min | Max | Frame | Unit |
    |-----|----------|-----|-----|-------|------|
    | ft_wrench | latest F/T sample (Fx, Fy, Fz, Tx, Ty, Tz), 100 Hz, tared | -500 | 500 | sensor | N, N·m |
    | ft_wrench_mean | mean of the 5 F/T samples of the last step | -500 | 500 | sensor | N, N·m |
    | q_rad | joint angles from RTDE (125 Hz, motor side) | -2π | 2π | joints | rad |
    | tcp_error_base_m | RTDE TCP minus the nominal path point | -0.1 | 0.1 | base | m |
    | tracker_error_base_m | tracker marker minus where a rigid arm on the nominal path puts it | -0.1 | 0.1 | base | m |
    | tracker_valid | 1 if a tracker is fitted and tracking, else 0 | 0 | 1 | - | - |
    | path_depth_m | nominal tip depth past the entry point | -0.1 | 0.1 | task z | m |
    | phase | one-hot approach / feed / retract | 0 | 1 | - | - |
    | correction_base_m | correction currently commanded | -0.01 | 0.01 | base | m |
    | feed_scale | feed override currently commanded | 0 | 4 | - | - |

    Sign convention: forces are those the environment (bone) exerts on the tool. Privileged state (true
    tip position and deflection, stage, hole, the specimen's hardness factor ``specimen_hardness``) is in
    ``info`` only.

    ## Rewards

    Per step: ``-w_dev · deviation_mm - w_force · lateral_force_n - w_smooth · |Δa|² - w_peak · Δpeak_n``,
    with the tip deviation from the planned axis and the true lateral force averaged over the step, and
    ``Δpeak_n`` how far this step's force raises the episode's running maximum: over an episode the last
    term sums to ``-w_peak`` times the peak lateral force (off by default, ``w_peak = 0``). Every term is in
    ``info["reward_terms"]``.

    ## Starting State

    Tip 3 mm above the planned entry point on the planned axis, arm unloaded, bone uncut. Sensor
    noise is drawn from the env's ``np_random`` (seeded by ``reset(seed=...)``).

    ## Episode End

    Terminated when the retract is complete (``info["metrics"]`` holds the episode metrics) or when
    the measured force exceeds ``force_limit_n`` (``info["failure"] = "force_limit"``). Truncated by the
    registration time limit (4000 steps, which the env applies itself too) or at three times the nominal
    duration; the episode metrics are in ``info["metrics"]`` then too, with ``info["metrics_truncated"] =
    True`` (they describe the part drilled). A shorter limit of your own (``gym.make(...,
    max_episode_steps=N)``) truncates outside the env, without them: read ``env.unwrapped.episode_metrics()``
    then, or wrap the env in :class:`drillgym.envs.wrappers.MetricsOnTruncation`, which puts them in ``info``
    (``metrics_truncated = True``) when a wrapper inside it truncates.

    ``reset(options=...)`` takes ``{"scenario": {...}}`` (scenario arguments from the table below, changed
    from this episode on) and ``{"effects": [...]}`` (unmodelled effects, :mod:`drillgym.envs.effects`); other keys
    are an error.

    ## Arguments

    | Argument | Default | Range | Unit | Meaning |
    |----------|---------|-------|------|---------|
    | beta_deg | 30 | [-40, 40] | deg | interaction angle β between the drill axis and the surface normal |
    | feed_mm_s | 0.5 | (0, 3] | mm/s | nominal feed rate |
    | spindle_rpm | 20000 | [1000, 60000] | rpm | spindle speed |
    | drill_diameter_mm | 1.5 | [0.5, 6] | mm | twist-drill diameter (118° point, 2 lips) |
    | stickout_mm | 37.9 | [10, 100] | mm | drill free length from the chuck (calibrated) |
    | depth_mm | 6 | [2, 30] | mm | target depth past the entry point |
    | cortical_thickness_mm | 8 | [0.3, 40] | mm | cortical layer thickness over the cancellous core |
    | bone | buffalo_femur | presets | - | specimen preset (``envs.drilling.BONE_PRESETS``) |
    | density_scale | 1 | [0.3, 3] | - | scales every cutting coefficient |
    | bone_variability | 0.05 | [0, 0.3] | - | std of the per-episode (seeded) hardness factor of the specimen |
    | ft_noise_n | 0.02 | [0, 2] | N | F/T force noise (std per axis) |
    | tracker_noise_mm | 0.05 | [0, 2] | mm | tracker noise (std per axis) |
    | latency_s | 0.014 | [0, 0.5] | s | command latency (Li: ~14 ms) |
    | servo_time_constant_s | 0.02 | [0.001, 0.5] | s | servo tracking lag |
    | tracker | True | - | - | whether a tracker is fitted |
    | force_limit_n | 40 | [1, 500] | N | safety stop on the measured force |

    Also ``cell_params`` (:class:`drillgym.envs.cell_params.CellParams`), ``bone_material`` (a custom
    :class:`drillgym.envs.drilling.BonePreset` replacing the named ``bone``), the reward weights
    ``reward_deviation_weight`` (per mm), ``reward_force_weight`` (per N), ``reward_smooth_weight``,
    ``reward_peak_force_weight`` (per N of episode peak), ``render_mode`` (``"rgb_array"``) and the frame
    size ``render_width_px``, ``render_height_px`` (320 × 240 by default), and ``pybullet_world`` (False: no
    PyBullet client, so no rendering; the physics does not use it; :mod:`drillgym.envs.batched` builds its
    episodes so). Invalid
    values raise ``ValueError`` naming the argument, its value and the allowed range. Unmodelled effects for
    the sim-to-real diagnosis (:mod:`drillgym.envs.effects`) are switched on with ``env.unwrapped.set_effects([...])``
    or ``reset(options={"effects": [...]})``; none are on by default.

    ## Version History

    * v1: the entry is guided by the hole wall (the drill walks on the inclined surface until the hole it
      cuts holds it) and the cutting coefficients are refitted to Li's uncompensated run
      (``docs/physics.md``); unknown arguments and ``reset`` options are errors; metrics on truncation too;
      ``render_width_px``/``render_height_px``. Results differ from v0 for every controller, so v0 is no
      longer registered: ``gym.make`` of the v0 id raises Gymnasium's ``DeprecatedEnv`` naming v1.
    * v0: initial release.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": round(1.0 / CONTROL_DT_S)}  # noqa: RUF012
    use_compiled_step = True
    """Without unmodelled effects (or with only :attr:`Effect.compiled` ones), step with the compiled kernel (:mod:`drillgym.envs.step_kernel`) from the next
    ``reset``; False keeps the Python step (the same physics, equal to rounding: ``tests/envs/test_step_kernel.py``)."""

    def __init__(
        self,
        render_mode: str | None = None,
        cell_params: CellParams | None = None,
        bone_material: BonePreset | None = None,
        reward_deviation_weight: float = 1.0,
        reward_force_weight: float = 0.1,
        reward_smooth_weight: float = 0.01,
        reward_peak_force_weight: float = 0.0,
        render_width_px: int = 320,
        render_height_px: int = 240,
        pybullet_world: bool = True,
        **scenario_kwargs: Any,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise UserError(f"render_mode={render_mode!r} is not supported; allowed: {self.metadata['render_modes']}")
        for name, px in (("render_width_px", render_width_px), ("render_height_px", render_height_px)):
            if not isinstance(px, int) or not 16 <= px <= 4096:
                raise UserError(f"{name}={px!r} must be an integer number of pixels in [16, 4096]")
        self.render_size_px = (render_width_px, render_height_px)
        if render_mode is not None and not pybullet_world:
            raise UserError(f"render_mode={render_mode!r} needs the PyBullet world; pybullet_world=False has none")
        _check_arguments(scenario_kwargs)
        self.scenario = Scenario.from_kwargs(**scenario_kwargs)
        self.render_mode = render_mode
        self.reward = RewardWeights(
            reward_deviation_weight, reward_force_weight, reward_smooth_weight, reward_peak_force_weight
        )
        self.cell_params = cell_params
        self.bone_material = bone_material
        self.action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
        self.observation_space = observation_space()  # type: ignore[assignment]
        self.recorder = SampleRecord()
        self.world: PyBulletWorld | None = (
            PyBulletWorld(visual_meshes=render_mode is not None) if pybullet_world else None
        )
        self.effects: EffectStack | None = None
        self._effects_attached = False
        self._cells: dict[Scenario, SimCell] = {}
        self._build(self.scenario)
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

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Start a new hole: tip 3 mm above the entry point, uncut bone, sensors re-seeded.

        ``options={"scenario": {...}}`` changes scenario arguments from this episode on (validated like
        the constructor's; the others keep their values): domain randomisation and log replay use it.
        ``options={"effects": [...]}`` switches unmodelled effects on from this episode on (see
        :meth:`set_effects`).
        ``options={"specimen_seed": k}`` drills the specimen that ``reset(seed=k)`` draws, with the sensor
        noise of this reset's ``seed``: one specimen under many noise draws (the emulator seeds its specimen the
        same way). With ``k == seed`` the episode is the plain ``reset(seed=seed)``'s, bit for bit.
        Every option is validated first: a reset that raises leaves the env (episode, effects, scenario, random
        stream) as it was.
        """
        opts = options or {}
        unknown = sorted(set(opts) - RESET_OPTIONS)
        if unknown:
            raise UserError(
                f"reset(options=...): unknown key(s) {unknown}; allowed: {sorted(RESET_OPTIONS)} "
                '(scenario arguments go inside options={"scenario": {...}})'
            )
        # Every option is checked before anything changes: a reset that raises leaves the env as it was
        # (its episode, effects, scenario and random stream), so a corrected reset starts cleanly.
        specimen_seed = _checked_specimen_seed(opts.get("specimen_seed"))
        effects = EffectStack(opts["effects"]) if opts.get("effects") else None
        changes = dict(opts.get("scenario") or {})
        scenario = Scenario.from_kwargs(**{**self.scenario.to_dict(), **changes}) if changes else None
        if self._kernel is not None:  # the last episode's fields back into the objects, before they change
            self._kernel.release()
        super().reset(seed=seed)
        if "effects" in opts:
            self.effects = effects
        if scenario is not None:
            self._build(scenario)
        self._reset_state(specimen_seed)
        return self._observation(), self._info()

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

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Apply one correction + feed override for 50 ms (5 physics updates / F/T samples)."""
        a = checked_action(action, "env state unchanged")
        terminated, truncated = self._advance(a, "step")
        src = self if self._kernel is None else self._kernel.v  # the compiled step's scalars, not read through
        deviation_m, lateral_n = src.step_deviation_m, src.step_lateral_n
        terms = self.reward.terms(deviation_m, lateral_n, a, self.prev_action, self.peak_lateral_n)
        self.peak_lateral_n = max(self.peak_lateral_n, lateral_n)
        self.step_terms = terms
        self.prev_action = a
        return self._observation(), float(sum(terms.values())), terminated, truncated, self._info()

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
        if self._kernel is not None:  # no effects, or only compiled ones (Effect.compiled)
            return self._advance_compiled(corr, scale)
        fx = self.effects
        delay_s = self.scenario.latency_s if fx is None else fx.command_delay_s(self, self.scenario.latency_s)
        self.pending.append((self.t_s + delay_s, corr, scale))  # unmodelled effects (envs.effects) may delay it
        sc = self.scenario
        rt = self.cell.R_base_task.T
        rtde_time = latest_sample_time_s(self.t_s + CONTROL_DT_S, RTDE_RATE_HZ)
        rec = self.recorder
        cell = self.cell
        offset, hook = (None, None) if fx is None else self._effects_begin_step(fx)
        cell.begin_step(self._chip_m(), self._advance_m())
        samples, times, phases, depths = self._run_samples(rt, offset, hook, rtde_time)
        arm = cell.sensor_arm_m
        wrenches = np.array([(f[0], f[1], f[2], -arm * f[1], arm * f[0], tq) for _, _, f, tq, _, _, _ in samples])
        deviations = [math.hypot(tip[0], tip[1]) for tip, *_ in samples]
        rows = rec.extend(SUBSTEPS_PER_STEP)  # the compiled step's layout (envs.sample_record)
        rows[:, OUT_T_S] = times
        rows[:, OUT_PHASE] = phases
        rows[:, OUT_STAGE] = [smp[5] for smp in samples]
        rows[:, OUT_DEPTH_CMD] = depths
        rows[:, OUT_DEVIATION] = deviations
        rows[:, OUT_TIP : OUT_TIP + 3] = [smp[0] for smp in samples]  # effects may read them below
        rows[:, OUT_CUTTING] = [1.0 if smp[6] else 0.0 for smp in samples]
        if fx is not None:
            wrenches = fx.sensor_wrenches(self, wrenches, rows[:, OUT_T_S].copy())
        readings = self.ft.sample_block(wrenches)
        forces = readings[:, :3]
        rows[:, OUT_FORCE : OUT_TORQUE + 3] = readings
        if self.failure is None and _max_norm_exceeds(forces, sc.force_limit_n):
            self.failure = "force_limit"
        if rtde_time >= self.t_s - 1e-12:
            self.rtde_tcp_base = cell.tcp_rtde_base_m()
        self.ft_last = readings[-1]
        self.ft_mean = np.add.reduce(readings, axis=0) / SUBSTEPS_PER_STEP  # readings.mean(axis=0), bit for bit
        self.cell.end_step()
        self._sample_tracker()
        rows[:, OUT_TRACKER_DEVIATION] = self.tracker_lateral_m
        self.step_deviation_m = sum(deviations) / SUBSTEPS_PER_STEP
        self.step_lateral_n = sum(math.hypot(f[0], f[1]) for _, _, f, *_ in samples) / SUBSTEPS_PER_STEP
        terminated = self.path.phase == Phase.DONE or self.failure is not None
        self.steps += 1
        at_limit = self.t_s >= self.max_time_s or self.steps >= MAX_EPISODE_STEPS
        truncated = self.truncated = (not terminated) and at_limit
        if terminated or truncated:
            self.metrics = self.episode_metrics()
        return terminated, truncated

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

    def _advance_compiled(self, corr: np.ndarray, scale: float) -> tuple[bool, bool]:
        """:meth:`_advance` without effects, in one compiled call (:mod:`drillgym.envs.step_kernel`)."""
        assert self._kernel is not None
        self._kernel.step(corr, scale)
        return self._ended()

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

    # ------------------------------------------------------------------ helpers
    def _run_samples(
        self, rt: np.ndarray, offset: tuple[float, float, float] | None, hook: Any, rtde_time: float
    ) -> tuple[list[SampleRow], list[float], list[int], list[float]]:
        """The step's F/T samples: tip balance rows, their times (s), path phases and commanded depths (m).

        The samples' servo targets follow the path and the queued commands, not the physics: they are
        collected first and the tip balance runs over them in one pass, cut where a feed change
        re-prepares the balance (the order of every operation is that of one sample after the other).
        """
        cell, path, pending = self.cell, self.path, self.pending
        cx, cy, cz = self._servo_xyz(rt, offset)
        times: list[float] = []
        phases: list[int] = []
        depths: list[float] = []
        targets: list[tuple[float, float, float]] = []
        samples: list[SampleRow] = []
        rtde_k = -1
        t_s = self.t_s
        for k in range(SUBSTEPS_PER_STEP):
            t_next = t_s + PHYSICS_DT_S
            while pending and pending[0][0] <= t_next + 1e-12:
                _, self.correction_base_m, scale = pending.popleft()
                if scale != self.feed_scale:
                    samples += cell.run(targets[len(samples) :])
                    self.feed_scale = scale
                    self.t_s = t_s  # _advance_m reads the time of this sample
                    cell.begin_step(self._chip_m(), self._advance_m())
                cx, cy, cz = self._servo_xyz(rt, offset)
            phase = path.phase
            s = path.advance(PHYSICS_DT_S, self.feed_scale)
            if t_s <= rtde_time < t_next:
                rtde_k = k
            targets.append((cx, cy, cz + s) if hook is None else hook(t_next, (cx, cy, cz + s)))
            times.append(t_next)
            phases.append(phase.value)
            depths.append(s)
            t_s = t_next
        samples += cell.run(targets[len(samples) :])
        self.t_s = t_s
        if rtde_k >= 0:  # the RTDE sample saw the servo-held tip before sample rtde_k
            self.rtde_tcp_base = cell.tcp_rtde_base_m(samples[rtde_k - 1][1] if rtde_k > 0 else None)
        return samples, times, phases, depths

    def _effects_begin_step(self, fx: EffectStack) -> tuple[tuple[float, float, float] | None, Any]:
        """Run the effects' step-start hooks; their servo/geometry offset (m, task frame) and target hook."""
        fx.begin_step(self)
        return fx.target_offset_task_m(self.cell.geometry_offset_task_m), fx.target_hook

    def _servo_xyz(self, rt: np.ndarray, offset: tuple[float, float, float] | None) -> list[float]:
        """Commanded correction in the task frame (m), plus the effects' servo/geometry offset if any."""
        xyz = (rt @ self.correction_base_m).tolist()
        if offset is not None:
            xyz = [xyz[0] + offset[0], xyz[1] + offset[1], xyz[2] + offset[2]]
        return xyz

    def _advance_m(self) -> float:
        """Axial advance of the commanded tip per physics update over this step (m): feed plus correction.

        The drill cuts sideways in proportion to how far it advances, so a correction that plunges the
        tip along its axis counts as advance too (the lateral cut resistance is per metre of advance).
        """
        corr_now = self.correction_base_m
        corr_end = corr_now
        for t_apply, corr, _ in self.pending:
            if t_apply <= self.t_s + CONTROL_DT_S + 1e-12:
                corr_end = corr
        dz_corr = 0.0 if corr_end is corr_now else float(self.cell.R_base_task[:, 2] @ (corr_end - corr_now))
        per_step = self.path.speed_m_s(self.feed_scale) * CONTROL_DT_S + dz_corr
        return max(per_step / SUBSTEPS_PER_STEP, 0.0)

    def _chip_m(self) -> float:
        """Chip thickness per lip (m) at the feed in force and the spindle's speed now (``cell.spindle_rpm``)."""
        sc = self.scenario
        return sc.geometry.chip_thickness_m(sc.feed_m_s * self.feed_scale, self.cell.spindle_rpm)

    def _sample_tracker(self) -> None:
        stamp = latest_sample_time_s(self.t_s, TRACKER_RATE_HZ)
        if stamp != self.tracker_stamp:
            self.tracker_stamp = stamp
            marker = self.cell.marker_base_m()
            if self.effects is not None:
                marker = self.effects.tracker_marker_base_m(self, marker, stamp)
            self.tracker_reading = self.tracker.sample(marker)
        planned = self.marker_start_base + self.cell.R_base_task @ np.array([0.0, 0.0, self.path.s_m - self.s_start_m])
        self.tracker_error_base = self.tracker_reading - planned
        lateral = self.cell.R_base_task.T @ self.tracker_error_base
        self.tracker_lateral_m = math.hypot(lateral[0], lateral[1])

    def _nominal_tcp_base(self) -> np.ndarray:
        return self.cell.entry_base_m + self.cell.R_base_task @ np.array([0.0, 0.0, self.path.s_m])

    def _observation(self) -> dict[str, np.ndarray]:
        if self._kernel is not None and self._kernel.started:
            return self._kernel.observation()
        tracking = len(self.recorder) > 0 and self.scenario.tracker
        return observation_of(
            self.ft_last,
            self.ft_mean,
            self.cell.q_motor_rad,
            self.rtde_tcp_base - self._nominal_tcp_base(),
            self.tracker_error_base if tracking else 0.0,
            1.0 if self.scenario.tracker else 0.0,
            self.path.s_m,
            int(self.path.phase),
            self.correction_base_m,
            self.feed_scale,
        )

    def _info(self) -> dict[str, Any]:
        if self._kernel is not None and self._kernel.started:
            return self._kernel.info()
        smp = self.cell.sample
        info: dict[str, Any] = {
            "t_s": self.t_s,
            "phase": int(self.path.phase),
            "stage": smp.stage,
            "depth_cmd_m": self.path.s_m,
            "tip_pos_task_m": np.array(smp.tip),
            "deviation_m": math.hypot(smp.tip[0], smp.tip[1]),
            "tip_deflection_robot_m": self.cell.tip_deflection_robot_m(),
            "tip_deflection_tool_m": self.cell.tip_deflection_tool_m(),
            "force_true_n": np.array(smp.force),
            "depth_local_m": smp.depth_local,
            "reward_terms": dict(self.step_terms),
            "failure": self.failure,
            "specimen_hardness": self.specimen_hardness,
        }
        if self.metrics is not None:
            info["metrics"] = dict(self.metrics)
            info["metrics_truncated"] = self.truncated
        return info

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

    def render(self) -> np.ndarray | None:
        """RGB frame of the cell (``render_mode="rgb_array"``), headless."""
        if self.render_mode != "rgb_array" or self.world is None:
            return None
        q = self.cell.q_actual_rad()
        self.world.set_joint_angles(q)
        self.world.place_drill(
            self.cell.flange_pose_base(q),
            self.cell.params.sensor_to_chuck_m,
            self.scenario.stickout_m,
            self.scenario.drill_diameter_m,
        )
        return self.world.render(self.cell.entry_base_m, *self.render_size_px)

    def close(self) -> None:
        """Release the PyBullet client."""
        if self.world is not None:
            self.world.close()
            self.world = None
        super().close()

    def tracker_marker_pose_base(self) -> np.ndarray:
        """True ``T_base_marker`` (privileged; for tests and diagnostics)."""
        return self.cell.kin.fk(self.cell.q_actual_rad(), TRACKER_FRAME)


def _checked_specimen_seed(value: Any) -> int | None:
    """``reset``'s ``specimen_seed`` option: None or a non-negative integer."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise UserError(f"reset(options={{'specimen_seed': {value!r}}}): a non-negative integer seed, or None")
    return int(value)
