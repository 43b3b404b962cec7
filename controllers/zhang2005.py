"""``zhang2005``: Zhang et al. 2005's real-time deformation compensation and controlled material removal.

* **Deformation compensation** (§III, Fig. 6): the F/T wrench, filtered and with the tool's gravity
  removed, is moved to the drill tip and turned into the joint deflection ``Δq = Kq⁻¹ Jᵀ W`` of the
  full coupled stiffness model; the joint references are offset by ``-Δq``, i.e. the tip target by
  ``-J Δq`` (all three axes: thrust that bends the arm sideways is compensated too).
* **Controlled material removal rate** (§IV, eq. 7-8, Fig. 8): the MRR ``w·d·f`` of a drill is
  ``π R² f``, set by the feed alone, and is regulated through the cutting (thrust) force: a PI on the
  feed speed holds the thrust at a reference. Off until the drill is fully engaged (the inclined entry
  should not be rushed), with anti-windup at the feed limits.

The two parts are usable separately (``deformation``, ``cmrr``). Units: SI; frames: base unless named.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.batch import unscale_actions, window_mean
from drillgym.controllers.models import RobotComplianceModel
from drillgym.envs.constants import CONTROL_DT_S, FEED_OVERRIDE_LOG2_MAX, MAX_CORRECTION_M, SUBSTEPS_PER_STEP
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan
from drillgym.envs.robot.compliance import KTHETA_LI2023_NM_RAD

GRAVITY_M_S2 = 9.81


@dataclass
class Zhang2005Config:
    """Deformation compensation and controlled-MRR settings."""

    deformation: bool = True
    """Compensate the arm's deflection from the measured wrench."""
    cmrr: bool = True
    """Regulate the thrust with the feed speed (controlled material removal rate)."""
    joint_stiffness_nm_rad: tuple[float, ...] = field(default_factory=lambda: tuple(KTHETA_LI2023_NM_RAD))
    """Kq, the controller's joint-stiffness estimate (N·m/rad); default Li's identified values."""
    filter_samples: int = 10
    """F/T samples averaged before use (100 Hz)."""
    tool_mass_kg: float = 0.0
    """Spindle + drill mass below the sensor for gravity removal (0: the sensor was tared in the drilling pose)."""
    tool_com_sensor_m: tuple[float, float, float] = (0.0, 0.0, 0.06)
    """Tool centre of mass in the sensor frame (m)."""
    thrust_ref_n: float = 8.0
    """Reference thrust F_r (N): a cortical-bone limit for a 1.5 mm drill."""
    kp_feed_mm_s_per_n: float = 0.05
    """Proportional gain of the feed PI ((mm/s)/N)."""
    ki_feed_mm_s_per_ns: float = 0.8
    """Integral gain of the feed PI ((mm/s)/(N·s)); the thrust rises ~4 N per mm/s in cortical bone."""
    cmrr_start_margin_mm: float = 0.5
    """CMRR engages this far past full engagement of the planned entry (mm)."""
    feed_scale_max: float = 2.0**FEED_OVERRIDE_LOG2_MAX
    """Highest feed the PI may command, relative to the plan's feed (default: the action's limit, 4;
    1 makes the CMRR a pure force limiter that only ever slows the feed)."""
    max_correction_m: float = MAX_CORRECTION_M
    """Clip on the correction per axis (m)."""

    def __post_init__(self) -> None:
        if self.filter_samples < 1:
            raise UserError(f"filter_samples={self.filter_samples} must be >= 1")
        if len(self.joint_stiffness_nm_rad) != 6 or min(self.joint_stiffness_nm_rad) <= 0:
            raise UserError(f"joint_stiffness_nm_rad={self.joint_stiffness_nm_rad} must be 6 positive values")
        if self.thrust_ref_n <= 0 or not math.isfinite(self.thrust_ref_n):
            raise UserError(f"thrust_ref_n={self.thrust_ref_n} must be a positive number of newtons")
        top = 2.0**FEED_OVERRIDE_LOG2_MAX
        if not (math.isfinite(self.feed_scale_max) and 2.0**-FEED_OVERRIDE_LOG2_MAX <= self.feed_scale_max <= top):
            raise UserError(f"feed_scale_max={self.feed_scale_max} must be in [{1 / top:g}, {top:g}]")


class Zhang2005Controller(Controller):
    """Real-time deformation compensation + controlled material removal rate.

    Batchable (:attr:`~drillgym.controllers.base.Controller.batchable`): the stiffness model's products run per
    episode, with the shapes one episode gives them, and everything else elementwise, so an episode's actions are
    the same bit for bit in any batch.
    """

    name = "zhang2005"
    batchable = True

    def __init__(self, config: Zhang2005Config | None = None) -> None:
        super().__init__()
        self.config = config or Zhang2005Config()

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Build the stiffness model for the plan's tool, then reset ``num_episodes`` episodes."""
        self.robot = RobotComplianceModel(plan.tcp_offset_m, np.asarray(self.config.joint_stiffness_nm_rad))
        self.R = plan.R_base_task
        self.tip_in_sensor_m = np.array([0.0, 0.0, plan.tcp_offset_m])
        entry = plan.drill_diameter_m / 2 * (1 / math.tan(math.radians(59.0)) + math.tan(abs(plan.beta_rad)))
        self.cmrr_start_depth_m = entry + self.config.cmrr_start_margin_mm * 1e-3
        self.feed_nominal_mm_s = plan.feed_m_s * 1e3
        super().set_plan(plan, num_episodes)

    def reset(self) -> None:
        """Empty the filter and the feed integrator of every episode."""
        self.window_steps = max(1, math.ceil(self.config.filter_samples / SUBSTEPS_PER_STEP))
        self.window = np.zeros((self.window_steps, self.num_episodes, 6))
        self.step = 0
        self.integral_mm_s = np.zeros(self.num_episodes)

    # ------------------------------------------------------------------ models
    def gravity_wrench_sensor(self) -> np.ndarray:
        """Wrench of the tool's weight in the sensor frame, minus what the tare already removed (zero here)."""
        return np.zeros(6)  # tared in the drilling pose, which the path keeps; kept as the hook Zhang describes

    def tip_wrench_base(self, wrench_sensor: np.ndarray) -> np.ndarray:
        """External wrench on the tool moved to the drill tip, base axes: (N, N·m)."""
        f_s = wrench_sensor[:3]
        tau_tip_s = wrench_sensor[3:] - _cross(self.tip_in_sensor_m, f_s)
        return np.concatenate([self.R @ f_s, self.R @ tau_tip_s])

    def deflection_base_m(self, q_rad: np.ndarray, wrench_sensor: np.ndarray) -> np.ndarray:
        """Tip displacement J Kq⁻¹ Jᵀ W of the arm under the measured wrench (m, base frame)."""
        j = self.robot.jacobian(q_rad)
        dq = self.robot.joints.joint_deflection_rad(j, self.tip_wrench_base(wrench_sensor))
        return j[:3] @ dq

    # ------------------------------------------------------------------ control
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Correction -J Δq and a PI-regulated feed scale."""
        return self.act_batch({k: np.asarray(v)[None] for k, v in obs.items()})[0]

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """:meth:`act` of every episode: observations (N, k) in, actions (N, 4) float32 out."""
        cfg = self.config
        n = self.num_episodes
        self.window[self.step % self.window_steps] = obs["ft_wrench_mean"]
        wrench = window_mean(self.window, self.step) - self.gravity_wrench_sensor()
        self.step += 1
        correction = np.zeros((n, 3))
        if cfg.deformation:
            q = obs["q_rad"]
            for i in range(n):
                correction[i] = np.clip(
                    -self.deflection_base_m(q[i], wrench[i]), -cfg.max_correction_m, cfg.max_correction_m
                )
        scale = np.ones(n)
        if cfg.cmrr:
            feeding = (obs["phase"][:, 1] > 0.5) & (obs["path_depth_m"][:, 0].astype(float) >= self.cmrr_start_depth_m)
            scale = np.where(feeding, self._feed_scale(thrust_n=-wrench[:, 2], update=feeding), 1.0)
        return unscale_actions(correction, scale)

    def _feed_scale(self, thrust_n: np.ndarray, update: np.ndarray) -> np.ndarray:
        """PI on the feed (mm/s) holding the thrust at the reference; clamped, with anti-windup.

        The integrators of the episodes in ``update`` move; the others keep theirs.
        """
        cfg = self.config
        error = cfg.thrust_ref_n - thrust_n
        lo = self.feed_nominal_mm_s * 2.0**-FEED_OVERRIDE_LOG2_MAX
        hi = self.feed_nominal_mm_s * cfg.feed_scale_max
        proportional = self.feed_nominal_mm_s + cfg.kp_feed_mm_s_per_n * error
        # anti-windup: the integrator never pushes the feed past its limits
        moved = np.minimum(
            np.maximum(self.integral_mm_s + cfg.ki_feed_mm_s_per_ns * error * CONTROL_DT_S, lo - proportional),
            hi - proportional,
        )
        self.integral_mm_s = np.where(update, moved, self.integral_mm_s)
        feed = np.minimum(np.maximum(proportional + self.integral_mm_s, lo), hi)
        return feed / self.feed_nominal_mm_s


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors: numpy's products and differences, in Python floats.

    The same numbers bit for bit (``tests/controllers/test_controller_batch.py``); numpy's ``cross`` spends most of
    its ≈ 40 µs a call moving axes.
    """
    a0, a1, a2 = a.tolist()
    b0, b1, b2 = b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
