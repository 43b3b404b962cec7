"""Gymnasium environment on a real UR5 (CB3) drilling cell, through ``ur_rtde``: the sim env's API."""

from __future__ import annotations

import math
import time
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from drillgym.envs.cell_params import R_BASE_TASK, CellParams
from drillgym.envs.constants import ACTION_DIM, APPROACH_START_M, CONTROL_DT_S, scale_action
from drillgym.envs.errors import UserError
from drillgym.envs.metrics import EpisodeRecorder, episode_metrics
from drillgym.envs.observation import observation_space
from drillgym.envs.plan import DrillPlan
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.devices import CellDevices
from drillgym.envs.real.episode import EpisodeStreams
from drillgym.envs.real.netft import NetFTCalibration
from drillgym.envs.real.poses import rotation_angle_rad, rotvec_to_matrix
from drillgym.envs.real.robot_link import LinkError
from drillgym.envs.real.safety import check_safety_bits
from drillgym.envs.real.servo import BLIND_FAULTS, CellGeometry, ServoLoop
from drillgym.envs.real.servo_process import RemoteServo
from drillgym.envs.reward import RewardWeights, checked_action
from drillgym.envs.scenario import Scenario
from drillgym.envs.task import DrillPath

TARE_S = 0.3
"""F/T samples averaged for the tare at the start pose (s)."""


class UR5BoneDrillRealEnv(gym.Env[dict[str, np.ndarray], np.ndarray]):
    """The simulated env's API on a real UR5 (CB3) with an ATI Net F/T and an optional tracker.

    ## Description

    Same task, spaces and scaling as ``drillgym/UR5BoneDrill-v1`` (see its docstring): any controller runs
    unchanged. Motion: ``servoL`` streamed at 125 Hz from a servo process of its own (``initPeriod`` /
    ``waitPeriod``); each cycle the nominal path advances by the elapsed time at the commanded feed override
    and the latest commanded correction is added (held between agent steps). ``step`` lasts one control
    period (50 ms of wall-clock time) and returns when it has passed. State from ``RTDEReceiveInterface``,
    forces from the Net F/T's RDT stream resampled to 100 Hz (10 ms bin means), tared at the start pose.

    ## Action Space

    ``Box(-1, 1, (4,), float32)``: tip correction (base frame, × ``MAX_CORRECTION_M``) and feed override
    ``2**(2 a)``, as in the sim. A NaN or infinite action raises ``ValueError`` before anything is sent.

    ## Observation Space

    The sim's ``Dict`` (:func:`drillgym.envs.observation.observation_space`), from measurements only: ``ft_wrench``
    (latest 10 ms bin), ``ft_wrench_mean`` (the step's bins), ``q_rad`` and ``tcp_error_base_m`` (RTDE),
    ``tracker_error_base_m`` / ``tracker_valid`` (the marker vs. where it was at the start pose moved along
    the path; 0 / 0 without a fresh reading), the path, and the command being streamed.

    ## Rewards

    ``-w_dev · tracker deviation (mm) - w_force · mean lateral F/T force (N) - w_smooth · |Δa|² - w_peak · Δpeak_n``
    (``Δpeak_n``: how far the mean lateral F/T force raises the episode's running maximum); no true tip
    on a real cell. Terms in ``info["reward_terms"]``.

    ## Starting State

    ``reset`` restarts ur_rtde's control program (no RTDE watchdog during the move), sets the TCP from the
    plan, checks the safety bits and that the TCP is within ``reset_max_distance_m`` and
    ``reset_max_angle_rad`` of the start pose (the tip 3 mm above the planned entry point on the planned
    axis; otherwise it raises without moving: jog closer), ``moveL``s there, tares the F/T sensor, arms the
    robot's RTDE watchdog and starts the stream. ``seed`` has no physical effect (it is logged).

    ## Episode End

    Terminated when the retract is done (``info["metrics"]``) or on a fault, with ``info["failure"]`` naming
    it and ``info["error"]`` saying what was seen: ``force_limit``, ``protective_stop``, ``safety_stop``,
    ``link_lost``, ``rtde_stale``, ``ft_stale``, ``watchdog_cycle``, ``workspace``, ``tracking``,
    ``program_stopped``, ``servo_refused``, ``agent_timeout``. Every fault commands ``servoStop`` first
    (``stopScript`` too when the link is lost); ``info["stop_result"]`` says what the robot answered.
    Truncated at three times the nominal duration.

    ## Arguments

    ``robot_host`` (required), ``ft_sensor`` (``HOST[:PORT]``; default: ``robot_host``), ``tracker``
    (``"none"`` or ``"udp:HOST[:PORT]"``), ``ft_calibration`` (:class:`drillgym.envs.real.netft.NetFTCalibration`),
    ``dry_run`` (no control interface at all: commands are only logged), ``command_log_path`` (JSONL of every
    command sent or, dry, not sent), ``servo_process`` (default True: the servo loop, the ``ur_rtde`` interfaces and
    the F/T stream run in a process of their own at real-time priority where the OS allows it, see
    :mod:`drillgym.envs.real.servo_process`, so the agent's compute cannot starve them; False: a thread in this
    process, which under load misses cycles and can stop on the watchdog, ``docs/deployment.md`` §7), ``safety_limits`` (:class:`drillgym.envs.real.config.SafetyLimits`),
    ``servo_params`` (:class:`drillgym.envs.real.config.ServoParams`), ``cell_params`` (the entry point in the base
    frame, sensor-to-chuck length, as registered on the real cell), the reward weights, and the sim's
    scenario arguments: they define the plan (β, feed, rpm, drill, stick-out, depth, cortical thickness,
    bone) and ``force_limit_n``; the sim-only ones (noise, latency, bone variability) are ignored.

    ## Version History

    * v1: follows the simulated env's version (the same task, reward and observation); v0 is no longer
      registered.
    * v0: initial release.
    """

    metadata = {"render_modes": []}  # noqa: RUF012

    def __init__(
        self,
        robot_host: str,
        ft_sensor: str | None = None,
        tracker: str | bool | None = "none",
        ft_calibration: NetFTCalibration | None = None,
        dry_run: bool = False,
        command_log_path: str | None = None,
        servo_process: bool = True,
        safety_limits: SafetyLimits | None = None,
        servo_params: ServoParams | None = None,
        cell_params: CellParams | None = None,
        reward_deviation_weight: float = 1.0,
        reward_force_weight: float = 0.1,
        reward_smooth_weight: float = 0.01,
        reward_peak_force_weight: float = 0.0,
        **scenario_kwargs: Any,
    ) -> None:
        if isinstance(tracker, bool):
            if tracker:
                raise UserError("tracker=True: name the tracker device, e.g. tracker='udp:HOST'; or 'none'")
            tracker = "none"
        tracker_spec = tracker or "none"
        self.scenario = Scenario.from_kwargs(**{**scenario_kwargs, "tracker": tracker_spec != "none"})
        self.params = cell_params or CellParams()
        self.limits = safety_limits or SafetyLimits()
        self.servo_params = servo_params or ServoParams()
        self.dry_run = bool(dry_run)
        self.reward = RewardWeights(
            reward_deviation_weight, reward_force_weight, reward_smooth_weight, reward_peak_force_weight
        )
        self.action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
        self.observation_space = observation_space()  # type: ignore[assignment]
        self.recorder = EpisodeRecorder()
        self.devices = CellDevices.open(
            robot_host,
            ft_sensor or robot_host,
            tracker_spec,
            ft_calibration or NetFTCalibration(),
            self.servo_params,
            self.dry_run,
            command_log_path,
            servo_process=servo_process,
        )
        self.servo: ServoLoop | RemoteServo | None = None
        self.streams: EpisodeStreams | None = None
        state = self.devices.link.state()
        self.rtde_tcp_base = np.asarray(state.tcp_pose[:3])
        self.tracker_reading = np.full(3, np.nan)
        self.closed = False

    # ------------------------------------------------------------------ plan
    @property
    def tcp_offset_m(self) -> float:
        """Flange-to-tip distance along the flange z axis (m): sensor, spindle and the measured stick-out."""
        return self.params.sensor_to_chuck_m + self.scenario.stickout_m

    @property
    def T_base_task(self) -> np.ndarray:
        """Task frame in the base frame (4x4): the registered entry point, the planned drill axis."""
        t = np.eye(4)
        t[:3, :3] = R_BASE_TASK
        t[:3, 3] = self.params.entry_point
        return t

    @property
    def plan(self) -> DrillPlan:
        """The surgical plan (as in the sim)."""
        return DrillPlan.from_scenario(self.scenario, self.T_base_task, self.tcp_offset_m)

    def _geometry(self) -> CellGeometry:
        return CellGeometry(self.params.entry_point, R_BASE_TASK, self.scenario.depth_m)

    # ------------------------------------------------------------------ gym API
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Move to the start pose, tare the F/T sensor, start streaming (see the class docstring)."""
        super().reset(seed=seed)
        if self.closed:
            raise RuntimeError("the env is closed")
        self._stop_stream()
        if options and options.get("scenario"):
            changes = {**self.scenario.to_dict(), **dict(options["scenario"])}
            self.scenario = Scenario.from_kwargs(**changes)
        link, geo = self.devices.link, self._geometry()
        if not self.dry_run:
            link.restart_program()
        link.set_tcp(np.array([0.0, 0.0, self.tcp_offset_m, 0.0, 0.0, 0.0]))
        start_pose = np.concatenate([geo.to_base(np.array([0.0, 0.0, -APPROACH_START_M])), geo.tool_rotvec])
        self._check_start(start_pose)
        if not link.move_l(start_pose, self.limits.approach_speed_m_s):
            raise LinkError(f"moveL to the start pose was refused by {link.host} (program not running or stopped)")
        bias, marker = self.devices.tare(TARE_S)
        if not self.dry_run:
            link.set_watchdog(self.limits.robot_watchdog_hz)
        path = DrillPath(self.scenario.depth_m, self.scenario.feed_m_s)
        self.max_time_s = 3.0 * path.nominal_duration_s()
        t0 = time.monotonic()
        self.recorder.clear()
        self.servo = self.devices.make_servo(
            bias, geo, path, self.limits, self.servo_params, self.scenario.force_limit_n, t0
        )
        self.streams = EpisodeStreams(self.recorder, self.devices, self.servo, geo, t0, bias, marker)
        self.prev_action = np.zeros(ACTION_DIM)
        self.peak_lateral_n = 0.0
        self.metrics: dict[str, float] | None = None
        self.step_terms: dict[str, float] = {}
        self.servo.start()
        obs = self.streams.observation(path.s_m)
        self.rtde_tcp_base, self.tracker_reading = self.streams.tcp_base, self.streams.tracker_reading
        return obs, self._info()

    def _check_start(self, start_pose: np.ndarray) -> None:
        state = self.devices.link.state()
        fault = check_safety_bits(state.safety_status_bits, 0.0)
        if fault is not None:
            raise RuntimeError(f"cannot start: {fault.message}")
        if self.dry_run:
            return
        dist = float(np.linalg.norm(state.tcp_pose[:3] - start_pose[:3]))
        angle = rotation_angle_rad(rotvec_to_matrix(state.tcp_pose[3:]), rotvec_to_matrix(start_pose[3:]))
        if dist > self.limits.reset_max_distance_m or angle > self.limits.reset_max_angle_rad:
            raise RuntimeError(
                f"the TCP is {dist * 1e3:.1f} mm and {math.degrees(angle):.1f} deg from the start pose "
                f"{np.round(start_pose, 4).tolist()}; jog it within {self.limits.reset_max_distance_m * 1e3:.0f} mm "
                f"and {math.degrees(self.limits.reset_max_angle_rad):.0f} deg first (nothing was moved)"
            )

    def step(self, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
        """Command one correction + feed override and let one control period (50 ms) pass."""
        a = checked_action(action, "nothing sent")
        if self.servo is None or self.streams is None or self.streams.ended:
            raise RuntimeError("step() before reset() or after the episode ended; call reset()")
        corr, scale = scale_action(a)
        self.servo.command(corr, scale)
        sample = self.streams.advance(CONTROL_DT_S)
        self.rtde_tcp_base, self.tracker_reading = self.streams.tcp_base, self.streams.tracker_reading
        lateral_n = sample.lateral_force_mean_n
        self.step_terms = self.reward.terms(
            sample.tracker_lateral_m, lateral_n, a, self.prev_action, self.peak_lateral_n
        )
        self.peak_lateral_n = max(self.peak_lateral_n, lateral_n)
        self.prev_action = a
        terminated = self.servo.fault is not None or sample.path_done
        truncated = not terminated and sample.t_s >= self.max_time_s
        if terminated or truncated:
            self.streams.ended = True
            self._stop_stream()
            self.metrics = self.episode_metrics()
        obs = self.streams.observation(sample.s_m)
        return obs, float(sum(self.step_terms.values())), terminated, truncated, self._info()

    def _info(self) -> dict[str, Any]:
        servo, streams = self.servo, self.streams
        info: dict[str, Any] = {"reward_terms": dict(self.step_terms), "failure": None, "error": None}
        if servo is not None and streams is not None:
            fault = servo.fault
            info.update(
                t_s=streams.t_s,
                phase=int(streams.phase),
                depth_cmd_m=streams.s_m,
                failure=None if fault is None else fault.reason,
                error=None if fault is None else f"{fault.message} (t = {fault.t_s:.3f} s)",
                stop_result=servo.stats.stop_result,
                missed_cycles=servo.stats.missed_cycles,
                servo_cycles=servo.stats.cycles,
                max_cycle_gap_s=servo.stats.max_gap_s,
                agent_lag_s=streams.agent_lag_s,
                tracker_valid=streams.tracker_valid,
            )
        if self.metrics is not None:
            info["metrics"] = dict(self.metrics)
        return info

    def episode_metrics(self) -> dict[str, float]:
        """Metrics of the episode so far (the F/T contact flag stands for the stage; no true deviation)."""
        return episode_metrics(self.recorder, self.scenario.entry_depth_m, self.scenario.depth_m, math.nan)

    def _stop_stream(self) -> None:
        if self.servo is not None:
            self.servo.stop()

    def close(self) -> None:
        """Stop streaming (``servoStop``), stop the control program (``stopScript``), disconnect everything."""
        if self.closed:
            return
        self.closed = True
        try:
            self._stop_stream()
            link = self.devices.link
            blind = self.servo is not None and self.servo.fault is not None and self.servo.fault.reason in BLIND_FAULTS
            if not self.dry_run and not blind and link.connected() and not link.wedged:
                try:
                    link.stop_script()
                except LinkError:
                    pass
        finally:
            self.devices.close()
            super().close()
