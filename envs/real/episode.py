"""One episode of the real cell, step by step: the clock, the resampled streams, the recorder, the observation.

Step k covers ``[t0 + k·dt, t0 + (k+1)·dt)`` of the monotonic clock (``t0``: the stream's start). At the end of
the window its F/T bins are closed (:class:`drillgym.envs.real.sampling.FTBinner`), the nominal path is read at each
bin (:func:`drillgym.envs.real.sampling.path_at`) and the per-sample channels are appended to the env's
:class:`drillgym.envs.metrics.EpisodeRecorder`, the same channels the sim records (true-tip ones NaN, the stage an F/T
contact flag). A fault ends the window at the fault's time: the recorder holds every sample up to it.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from drillgym.envs.constants import APPROACH_START_M
from drillgym.envs.metrics import EpisodeRecorder
from drillgym.envs.observation import pack_observation
from drillgym.envs.real.devices import CellDevices
from drillgym.envs.real.metrics import contact_flags
from drillgym.envs.real.robot_link import LinkError
from drillgym.envs.real.sampling import FTBinner, path_at
from drillgym.envs.real.servo import CellGeometry, ServoLoop
from drillgym.envs.real.servo_process import RemoteServo
from drillgym.envs.task import Phase

ARRIVAL_GRACE_S = 0.002
"""Wait this long past a window's end for its last F/T records to arrive (s)."""
_NAN3 = (math.nan, math.nan, math.nan)


@dataclass(frozen=True)
class StepSample:
    """What one step measured."""

    t_s: float
    s_m: float
    path_done: bool
    tracker_lateral_m: float
    """Tracker deviation across the planned axis at the end of the step (m; 0 without a valid reading)."""
    lateral_force_mean_n: float
    """Mean lateral F/T force over the step's samples (N)."""


class EpisodeStreams:
    """Collects one episode's measurements, one control period at a time."""

    def __init__(
        self,
        recorder: EpisodeRecorder,
        devices: CellDevices,
        servo: ServoLoop | RemoteServo,
        geometry: CellGeometry,
        t0: float,
        ft_bias: np.ndarray,
        marker_start_base_m: np.ndarray | None,
    ) -> None:
        self.rec, self.devices, self.servo, self.geo, self.t0 = recorder, devices, servo, geometry, t0
        self.binner = FTBinner(t0, ft_bias)
        self.k = 0
        self.t_s = 0.0
        self.s_m = -APPROACH_START_M
        self.phase = Phase.APPROACH
        self.ended = False
        self.agent_lag_s = 0.0
        self.ft_last = np.zeros(6)
        self.ft_mean = np.zeros(6)
        self.tcp_base = np.asarray(servo.state.tcp_pose[:3], dtype=float)
        self.q_rad = np.asarray(servo.state.q_rad, dtype=float)
        self.marker_start = marker_start_base_m
        self.tracker_reading = np.full(3, np.nan)
        self.tracker_valid = False
        self.tracker_error = np.zeros(3)
        self.tracker_lateral_m = 0.0

    def advance(self, dt_s: float) -> StepSample:
        """Wait for the end of the current window (or a fault) and record it."""
        servo = self.servo
        window_start, window_end = self.t0 + self.k * dt_s, self.t0 + (self.k + 1) * dt_s
        self.agent_lag_s = max(time.monotonic() - window_start, 0.0)
        servo.ended.wait(timeout=max(window_end + ARRIVAL_GRACE_S - time.monotonic(), 0.0))
        servo.sync()
        if servo.fault is not None:
            t_close = min(self.t0 + servo.fault.t_s, window_end)
        else:
            rest = window_end + ARRIVAL_GRACE_S - time.monotonic()
            if rest > 0:  # the path ended early in the window: the robot holds, record the whole window
                time.sleep(rest)
            t_close = window_end
        self.k += 1
        records = self.devices.ft.since(self.binner.open_bin_start)
        times, wrenches = self.binner.bins_until(records, t_close)
        self._read_robot()
        self._read_tracker()
        lateral = 0.0
        if times:
            self._append(times, wrenches)
            self.ft_last, self.ft_mean = wrenches[-1], wrenches.mean(axis=0)
            lateral = float(np.mean(np.hypot(wrenches[:, 0], wrenches[:, 1])))
        self.t_s = times[-1] if times else self.t_s
        done = servo.fault is None and servo.done_t_s is not None and servo.done_t_s <= window_end - self.t0
        return StepSample(self.t_s, self.s_m, done, self.tracker_lateral_m, lateral)

    def _append(self, times: list[float], wrenches: np.ndarray) -> None:
        s, n = self.servo, len(times)
        if s.history_t:
            depth, phases = path_at(times, s.history_t, s.history_s, s.history_phase)
        else:  # the stream failed before its first cycle: the path has not moved
            depth, phases = [self.s_m] * n, [int(self.phase)] * n
        rec = self.rec
        previous = np.asarray(rec.ft_force_n[-4:]) if rec.ft_force_n else None
        rec.t_s.extend(times)
        rec.phase.extend(phases)
        rec.stage.extend(contact_flags(wrenches[:, :3], previous))
        rec.depth_cmd_m.extend(depth)
        rec.deviation_m.extend([math.nan] * n)
        rec.ft_force_n.extend(wrenches[:, :3])
        rec.ft_torque_nm.extend(wrenches[:, 3:])
        rec.tip_task_m.extend([_NAN3] * n)
        rec.tracker_deviation_m.extend([self.tracker_lateral_m if self.tracker_valid else math.nan] * n)
        self.s_m, self.phase = depth[-1], Phase(phases[-1])

    def _read_robot(self) -> None:
        try:
            state = self.servo.robot_state()
        except LinkError:
            state = self.servo.state
        self.tcp_base = np.asarray(state.tcp_pose[:3], dtype=float)
        self.q_rad = np.asarray(state.q_rad, dtype=float)

    def _read_tracker(self) -> None:
        reading = self.devices.tracker.latest()
        limit = self.servo.limits.tracker_stale_s
        fresh = reading is not None and time.monotonic() - reading.t_recv_s <= limit
        self.tracker_valid = bool(fresh and self.marker_start is not None)
        if not self.tracker_valid or reading is None or self.marker_start is None:
            self.tracker_reading = np.full(3, np.nan)
            self.tracker_error = np.zeros(3)
            self.tracker_lateral_m = 0.0
            return
        self.tracker_reading = reading.position_base_m
        planned = self.marker_start + self.geo.R_base_task @ np.array([0.0, 0.0, self.s_m + APPROACH_START_M])
        self.tracker_error = self.tracker_reading - planned
        lateral = self.geo.R_base_task.T @ self.tracker_error
        self.tracker_lateral_m = math.hypot(lateral[0], lateral[1])

    def observation(self, s_m: float) -> dict[str, np.ndarray]:
        """The observation at nominal depth ``s_m`` (the sim's keys, measured values only)."""
        phase = np.zeros(3)
        phase[min(int(self.phase), 2)] = 1.0
        corr, scale = self.servo.current_command()
        nominal = self.geo.to_base(np.array([0.0, 0.0, s_m]))
        return pack_observation(
            {
                "ft_wrench": self.ft_last,
                "ft_wrench_mean": self.ft_mean,
                "q_rad": self.q_rad,
                "tcp_error_base_m": self.tcp_base - nominal,
                "tracker_error_base_m": self.tracker_error if self.rec.t_s else np.zeros(3),
                "tracker_valid": np.array([1.0 if self.tracker_valid else 0.0]),
                "path_depth_m": np.array([s_m]),
                "phase": phase,
                "correction_base_m": corr,
                "feed_scale": np.array([scale]),
            }
        )
