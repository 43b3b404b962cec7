"""``li2023``: Li et al. 2023's force-position hybrid compensator (§2.3, Figs. 6-7).

* **Offline** (Fig. 6, upper path): before drilling, the planned path is shifted against the drill's
  predicted bending, ``ΔP = -k_D⁻¹ F``, with ``F`` the unbalanced force of the controller's own
  multi-stage force model along the planned depth and ``k_D`` the cantilever stiffness.
* **Online** (Fig. 6, lower path): the F/T force, filtered over 20 samples at 100 Hz, is turned into
  the tool's deviation ``Δx = C_D T₁ F_f + T₂ K_FD⁻¹ F_f`` (robot compliance + drill bending) plus the
  correction the robot is already executing (measured by RTDE), so ``Δx`` is the tip's deviation
  from the planned path.
* **PID on adjacent points** (eq. 14-15): every 600 ms trajectory point i, ``Δd_i = Δx_i - Δx_{i-1}``
  and ``u_i = KP Δd_i + KI Σ Δd + KD (Δd_i - Δd_{i-1})``; KI's sum is the deviation itself, KP acts on
  its change between points (the paper's "speed up the response").
* **Path prediction** (Fig. 7): at point i the robot is already moving to P_{i+1}, so u_i is added
  to the original target P_{i+2}; the robot moves linearly between corrected points.

Compensation is applied across the drill axis (both lateral axes by default; Li's X only with
``axes="x"``), never along it. Units: SI; frames: base unless named.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from drillgym.controllers.base import Controller
from drillgym.controllers.batch import matvec, window_mean
from drillgym.controllers.li2023_step import actions_into, offline_into, online_into
from drillgym.controllers.models import (
    LI2023_MODEL_PEAK_N,
    OfflineForceModel,
    RobotComplianceModel,
    tool_compliance_m_n,
)
from drillgym.controllers.stacked_models import StackedOfflineModels
from drillgym.envs.constants import CONTROL_DT_S, MAX_CORRECTION_M, SUBSTEPS_PER_STEP
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan


@dataclass
class Li2023Config:
    """Gains and timing of the hybrid compensator (defaults: the paper's best setting)."""

    kp: float = 4.0
    """Proportional gain on the change of deviation between adjacent points (Li: 4.0 best)."""
    ki: float = 0.25
    """Gain on the accumulated deviation, i.e. on the deviation itself (Li gives no value). Low because
    pushing on a drill whose hole is already cut mostly bends the drill: the wall yields slowly."""
    kd: float = 0.0
    """Gain on the change of the change (Li gives no value)."""
    filter_samples: int = 20
    """F/T samples averaged per compensation (Li: 20 at 100 Hz = 0.2 s)."""
    point_period_s: float = 0.6
    """Time per trajectory point (Li: 600 ms)."""
    prediction_points: int = 2
    """u_i is applied at P_{i + this} (Li's path prediction: 2)."""
    offline: bool = True
    """Apply the offline correction from the force model."""
    online: bool = True
    """Apply the online force-feedback correction."""
    model_peak_force_n: float = LI2023_MODEL_PEAK_N
    """Scale of the controller's force model: its peak at β 30°, 0.5 mm/s, fitted by least squares to the
    F/T force of an uncompensated trial hole (:func:`drillgym.controllers.models.fit_model_peak_n`)."""
    tool_effective_diameter_ratio: float = 0.85
    """Bending diameter of the fluted drill over its nominal diameter, for k_D."""
    max_correction_m: float = MAX_CORRECTION_M
    """Clip on the total correction per axis (m)."""
    count_executed_correction: bool = True
    """Add the correction the robot is executing (RTDE) to the force-based deflection, so Δx is the tip's
    deviation from the planned path; ``False`` is Li's eq. 13 literally (deflection only)."""
    axes: str = "xy"
    """Task axes compensated: ``"xy"`` (both across the drill) or ``"x"`` (Li's main deviation direction only;
    here the spindle's tangential force also pushes the tip along y, ~0.4 of x)."""
    y_gain: float = 1.0
    """Multiplier on the total correction (offline + online) along task y, across the plane of inclination,
    where the spindle's tangential cutting force pushes the tip (Li has one gain for both axes: 1)."""

    def __post_init__(self) -> None:
        if self.filter_samples < 1 or self.filter_samples % SUBSTEPS_PER_STEP:
            raise UserError(
                f"filter_samples={self.filter_samples} must be a positive multiple of {SUBSTEPS_PER_STEP} "
                "(F/T samples per agent step)"
            )
        steps = self.point_period_s / CONTROL_DT_S
        whole = math.isfinite(steps) and round(steps) >= 1 and abs(steps - round(steps)) <= 1e-9
        if not whole:  # at least one agent step per point: a picosecond period would give 0 steps per point
            raise UserError(f"point_period_s={self.point_period_s} must be a positive multiple of {CONTROL_DT_S} s")
        if self.prediction_points < 1:
            raise UserError(f"prediction_points={self.prediction_points} must be >= 1")
        if not all(math.isfinite(v) for v in (self.kp, self.ki, self.kd)):
            raise UserError("kp, ki and kd must be finite")
        if not (math.isfinite(self.y_gain) and 0.0 <= self.y_gain <= 3.0):
            raise UserError(f"y_gain={self.y_gain} must lie in [0, 3]")


_kernels_loaded = False
"""Whether this process has called li2023's compiled kernels (:meth:`Li2023Controller._load_kernels`)."""


def lateral_projector(R_base_task: np.ndarray, axes: str) -> np.ndarray:
    """Projector onto the compensated task axes (``"x"`` or ``"xy"``), in the base frame (3, 3)."""
    if axes not in ("x", "xy"):
        raise UserError(f"axes={axes!r} must be 'x' or 'xy'")
    cols = [0] if axes == "x" else [0, 1]
    return sum((np.outer(R_base_task[:, i], R_base_task[:, i]) for i in cols), np.zeros((3, 3)))


class Li2023Controller(Controller):
    """Force-position hybrid compensation with path prediction.

    Batchable: ``set_plan(plan, num_episodes=N)`` then :meth:`act_batch` runs N episodes of one plan in lockstep;
    :meth:`act` is a batch of one. Every operation is elementwise over the batch (the 3x3 products are written
    out, no BLAS call whose rounding could depend on the batch size), so an episode's actions are the same bit
    for bit whatever batch it runs in.
    """

    name = "li2023"
    batchable = True

    def __init__(self, config: Li2023Config | None = None) -> None:
        super().__init__()
        self.config = config or Li2023Config()
        self.steps_per_point = round(self.config.point_period_s / CONTROL_DT_S)

    def set_plan(self, plan: DrillPlan, num_episodes: int = 1) -> None:
        """Build the controller's own models for this plan, then reset ``num_episodes`` episodes."""
        robot = RobotComplianceModel(plan.tcp_offset_m)
        self.robots: list[RobotComplianceModel] = [robot] * num_episodes
        """Each episode's robot compliance model."""
        self.C_tool: np.ndarray = tool_compliance_m_n(plan, self.config.tool_effective_diameter_ratio)
        """Drill compliance at the tip (m/N, task axes): (3, 3) shared, or (N, 3, 3) per episode once stacked."""
        model = OfflineForceModel.for_plan(plan, self.config.model_peak_force_n)
        self.offline_model: OfflineForceModel | StackedOfflineModels = model
        """The offline force model: the plan's, or one per episode once stacked (read in one call)."""
        self._model_rows = StackedOfflineModels([model] * num_episodes)
        """The offline model of each episode in the form the compiled step reads (one table, shared)."""
        self.R: np.ndarray = plan.R_base_task
        """Rotation task -> base: (3, 3) shared, or (N, 3, 3) per episode once stacked."""
        self.lateral: np.ndarray = lateral_projector(self.R, self.config.axes)
        """Projector across the drill (base frame): (3, 3) shared, or (N, 3, 3) per episode once stacked."""
        cfg = self.config
        self._gains(cfg.kp, cfg.ki, cfg.kd, np.array([cfg.y_gain]))
        super().set_plan(plan, num_episodes)
        self._load_kernels()

    def _load_kernels(self) -> None:
        """Call the step's compiled kernels once per process, on scratch data of this controller's layouts.

        numba loads a kernel's machine code at its first call in a process (≈ 10 ms each): here, at the first plan,
        rather than at the first hole's first step, where a real cell's 50 ms step would pay it. Nothing is kept.
        """
        global _kernels_loaded
        if _kernels_loaded:
            return
        n = self.num_episodes
        self._actions(np.zeros(n), np.zeros((n, 3)))
        online_into(self.point_times_s.copy(), self.point_corrections.copy(), self.point_ring.copy(), 0.0,
                    self.config.point_period_s, np.empty((n, 3)))  # fmt: skip
        matvec(self.R, np.zeros((n, 3)))
        _kernels_loaded = True

    def _gains(self, kp: Any, ki: Any, kd: Any, y_gain: np.ndarray) -> None:
        """The gains as the step uses them.

        The config's floats, or one per episode once stacked ((N, 1)); the y gain (N,), or (1,) shared.
        """
        self.kp, self.ki, self.kd = kp, ki, kd
        self.y_gain = y_gain
        self._y_any = bool(np.any(y_gain != 1.0))
        self._y_all = bool(np.all(y_gain != 1.0))

    def stack_key(self) -> tuple[Any, ...] | None:
        """Controllers with equal keys step together once stacked: the same timing, switches and limits."""
        c = self.config
        return (
            type(self).__name__,
            c.filter_samples,
            c.point_period_s,
            c.prediction_points,
            c.offline,
            c.online,
            c.max_correction_m,
            c.count_executed_correction,
        )

    @classmethod
    def stack(cls, controllers: Sequence[Controller]) -> Li2023Controller:
        """One controller stepping ``controllers`` (each set to its plan, one episode) as a batch, row i the i-th's.

        Each episode keeps its own plan's models and its own gains; every operation stays elementwise, so row i's
        actions are the i-th controller's, bit for bit.
        """
        parts = [c for c in controllers if isinstance(c, Li2023Controller)]
        keys = {c.stack_key() for c in parts}
        if len(parts) != len(controllers) or len(keys) != 1 or any(c.num_episodes != 1 for c in parts):
            raise UserError("only li2023 controllers of one episode each, with the same timing and switches, stack")
        first = parts[0]
        out = cls(first.config)
        out.robots = [c.robots[0] for c in parts]
        out.C_tool = np.stack([np.broadcast_to(c.C_tool, (3, 3)) for c in parts])
        models = [cast(OfflineForceModel, c.offline_model) for c in parts]  # one episode each: the plan's model
        out.offline_model = out._model_rows = StackedOfflineModels(models)
        out.R = np.stack([c.R for c in parts])
        out.lateral = np.stack([c.lateral for c in parts])
        kp, ki, kd = (np.array([getattr(c.config, name) for c in parts])[:, None] for name in ("kp", "ki", "kd"))
        out._gains(kp, ki, kd, np.array([c.config.y_gain for c in parts]))
        out.plan = first.plan
        out.num_episodes = len(parts)
        out.reset()
        return out

    def reset(self) -> None:
        """Empty the force filter, the PID memory and the queued corrections of every episode."""
        n = self.num_episodes
        self.window_steps = self.config.filter_samples // SUBSTEPS_PER_STEP
        self.force_window = np.zeros((self.window_steps, n, 3))
        self.tcp_window = np.zeros((self.window_steps, n, 3))
        self.step = 0
        self.prev_dx = np.zeros((n, 3))
        self.prev_dd = np.zeros((n, 3))
        self.sum_dd = np.zeros((n, 3))
        # the online correction's corrected points, a queue (ring): time (s), each episode's correction (m, base)
        size = self.config.prediction_points + 3  # at most prediction_points + 2 are queued (a full ring grows)
        self.point_times_s = np.zeros(size)
        self.point_corrections = np.zeros((size, n, 3))
        self.point_ring = np.array([0, 1])
        """The queue's first slot and its length: one point at t = 0, no correction."""

    # ------------------------------------------------------------------ models
    def offline_correction_base_m(self, depth_m: float | np.ndarray) -> np.ndarray:
        """ΔP = -k_D⁻¹ F_model at the planned depth, lateral, base frame (m): (3,) for a depth, (N, 3) for N.

        Once stacked, N depths are the N episodes' (each read in its own model, with its own matrices).
        """
        depth = np.asarray(depth_m, dtype=float)
        d = depth.ravel()
        m = self._model_rows
        model_of = m.model_of if d.size == m.model_of.size else np.zeros(d.size, dtype=np.int64)
        if (m.sizes.size > 1 or self.R.ndim == 3) and d.size != self.num_episodes:
            raise UserError(f"{d.size} depths for {self.num_episodes} stacked episodes")
        out = np.empty((d.size, 3))
        offline_into(d, m.depth_m, m.lateral_task_n, m.sizes, model_of, _rows(self.lateral), _rows(self.R),
                     _rows(self.C_tool), out)  # fmt: skip
        return out[0] if depth.ndim == 0 else out

    def deviation_estimate_base_m(
        self, q_rad: np.ndarray, tcp_error_base_m: np.ndarray, force_sensor_n: np.ndarray
    ) -> np.ndarray:
        """Δx: executed correction (RTDE) + robot deflection C_D T₁ F + drill bending T₂ K_FD⁻¹ F; lateral.

        ``tcp_error_base_m`` and ``force_sensor_n`` are averaged over the same filter window. One episode's
        arguments ((6,), (3,), (3,)) give (3,); N episodes' ((N, 6), (N, 3), (N, 3)) give (N, 3).
        """
        one = np.ndim(force_sensor_n) == 1
        q = np.atleast_2d(np.asarray(q_rad, dtype=float))
        tcp = np.atleast_2d(np.asarray(tcp_error_base_m, dtype=float))
        force = np.atleast_2d(np.asarray(force_sensor_n, dtype=float))
        f_base = matvec(self.R, force)
        c_robot = np.stack([robot.translational_compliance_m_n(qi) for robot, qi in zip(self.robots, q, strict=True)])
        robot = matvec(c_robot, f_base)
        tool = matvec(self.R, matvec(self.C_tool, force))
        executed = tcp if self.config.count_executed_correction else np.zeros_like(tcp)
        out = matvec(self.lateral, executed + robot + tool)
        return out[0] if one else out

    # ------------------------------------------------------------------ control
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """Correction = offline profile + online PID correction (interpolated between points)."""
        return self.act_batch({k: np.asarray(v)[None] for k, v in obs.items()})[0]

    def act_batch(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """:meth:`act` of every episode: observations (N, k) in, actions (N, 4) float32 out."""
        cfg = self.config
        n = self.num_episodes
        t = self.step * CONTROL_DT_S
        slot = self.step % self.window_steps
        self.force_window[slot] = obs["ft_wrench_mean"][:, :3]
        self.tcp_window[slot] = obs["tcp_error_base_m"]
        if cfg.online and self.step % self.steps_per_point == 0:
            self._compensation_point(obs, t)
        online = np.zeros((n, 3))
        if cfg.online:
            online_into(self.point_times_s, self.point_corrections, self.point_ring, t + CONTROL_DT_S,
                        cfg.point_period_s, online)  # fmt: skip
        self.step += 1
        return self._actions(obs["path_depth_m"][:, 0].astype(float), online)

    def _actions(self, depth_m: np.ndarray, online_base_m: np.ndarray) -> np.ndarray:
        """Every episode's action (N, 4) float32 from its nominal depth (m) and online correction (m, base).

        Offline + online correction, the y gain, the clips and the action, as the numpy expressions give them
        (:func:`~drillgym.controllers.li2023_step.actions_into`).
        """
        n, cfg, model = self.num_episodes, self.config, self._model_rows
        actions = np.empty((n, 4), dtype=np.float32)
        actions_into(depth_m, cfg.offline, model.depth_m, model.lateral_task_n, model.sizes, model.model_of,
                     _rows(self.lateral), _rows(self.R), _rows(self.C_tool), online_base_m, self.y_gain, self._y_any,
                     self._y_all, cfg.max_correction_m, np.empty((n, 3)), actions)  # fmt: skip
        return actions

    def _compensation_point(self, obs: dict[str, np.ndarray], t: float) -> None:
        cfg = self.config
        force = window_mean(self.force_window, self.step)
        dx = self.deviation_estimate_base_m(obs["q_rad"], window_mean(self.tcp_window, self.step), force)
        dd = dx - self.prev_dx
        self.sum_dd = self.sum_dd + dd
        u = self.kp * dd + self.ki * self.sum_dd + self.kd * (dd - self.prev_dd)
        self.prev_dx, self.prev_dd = dx, dd
        t_apply = t + cfg.prediction_points * cfg.point_period_s
        target = np.clip(-u, -cfg.max_correction_m, cfg.max_correction_m)
        self._queue_point(t_apply, target)

    def _queue_point(self, t_s: float, correction_base_m: np.ndarray) -> None:
        """Append a corrected point (time s, (N, 3) corrections m) to the queue, growing a full ring."""
        first, count = (int(v) for v in self.point_ring)
        size = self.point_times_s.size
        if count == size:  # unroll the ring into one twice its size
            order = (first + np.arange(size)) % size
            self.point_times_s = np.concatenate([self.point_times_s[order], np.zeros(size)])
            self.point_corrections = np.concatenate(
                [self.point_corrections[order], np.zeros_like(self.point_corrections)]
            )
            first, size = 0, 2 * size
            self.point_ring[0] = 0
        slot = (first + count) % size
        self.point_times_s[slot] = t_s
        self.point_corrections[slot] = correction_base_m
        self.point_ring[1] = count + 1


def _rows(m: np.ndarray) -> np.ndarray:
    """A matrix shared by the batch (3, 3) as (1, 3, 3); one per episode (N, 3, 3) as it is."""
    return m[None] if m.ndim == 2 else m
