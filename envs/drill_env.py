"""Gymnasium environment: a UR5 drilling an inclined bone surface (Li et al. 2023's experiment)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.envs.cell_params import CellParams
from drillgym.envs.constants import (
    ACTION_DIM,
    CONTROL_DT_S,
)
from drillgym.envs.drilling.bone import BonePreset
from drillgym.envs.effects.base import EffectStack
from drillgym.envs.env_arguments import RESET_OPTIONS, check_arguments, checked_specimen_seed
from drillgym.envs.episode import DrillEpisode
from drillgym.envs.errors import UserError
from drillgym.envs.observation import observation_space
from drillgym.envs.pybullet_world import PyBulletWorld
from drillgym.envs.reward import RewardWeights, checked_action
from drillgym.envs.scenario import Scenario


class UR5BoneDrillEnv(DrillEpisode, gym.Env[dict[str, np.ndarray], np.ndarray]):
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
        check_arguments(scenario_kwargs)
        self.scenario = Scenario.from_kwargs(**scenario_kwargs)
        self.render_mode = render_mode
        self.reward = RewardWeights(
            reward_deviation_weight, reward_force_weight, reward_smooth_weight, reward_peak_force_weight
        )
        self.cell_params = cell_params
        self.bone_material = bone_material
        self.action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
        self.observation_space = observation_space()  # type: ignore[assignment]
        self.world: PyBulletWorld | None = (
            PyBulletWorld(visual_meshes=render_mode is not None) if pybullet_world else None
        )
        self._init_episode(self.scenario)

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
        self.begin_episode(seed=seed, options=options)
        return self._observation(), self._info()

    def begin_episode(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> None:
        """:meth:`reset` without making its observation and info (a batch of episodes reads its own arrays)."""
        opts = options or {}
        unknown = sorted(set(opts) - RESET_OPTIONS)
        if unknown:
            raise UserError(
                f"reset(options=...): unknown key(s) {unknown}; allowed: {sorted(RESET_OPTIONS)} "
                '(scenario arguments go inside options={"scenario": {...}})'
            )
        # Every option is checked before anything changes: a reset that raises leaves the env as it was
        # (its episode, effects, scenario and random stream), so a corrected reset starts cleanly.
        specimen_seed = checked_specimen_seed(opts.get("specimen_seed"))
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
