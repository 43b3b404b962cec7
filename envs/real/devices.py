"""The real cell's devices, opened together and closed together: robot link, F/T sensor, tracker.

By default they are opened in the agent's process and the servo loop runs as a thread there. With
``servo_process=True`` the robot link and the F/T stream live in the servo process
(:mod:`drillgym.envs.real.servo_process`) with the servo loop, and the agent's process holds stand-ins with the
same interface.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.real.command_log import CommandLog
from drillgym.envs.real.config import SafetyLimits, ServoParams
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration, NetFTClient
from drillgym.envs.real.robot_link import LinkError, RobotLink
from drillgym.envs.real.servo import CellGeometry, ServoLoop
from drillgym.envs.real.servo_process import RemoteFT, RemoteLink, RemoteServo, ServoProcess, ServoProcessSpec
from drillgym.envs.real.tracker import Tracker, make_tracker
from drillgym.envs.task import DrillPath


def split_host_port(spec: str, default_port: int) -> tuple[str, int]:
    """``"HOST"`` or ``"HOST:PORT"`` -> ``(host, port)``."""
    host, _, port = spec.partition(":")
    if not host:
        raise UserError(f"{spec!r} does not name a host")
    return host, int(port) if port else default_port


@dataclass
class CellDevices:
    """Open connections to the robot, the F/T sensor and the tracker."""

    link: RobotLink | RemoteLink
    ft: NetFTClient | RemoteFT
    tracker: Tracker
    process: ServoProcess | None = None
    """The servo process (None: the loop runs as a thread in this process)."""

    @classmethod
    def open(
        cls,
        robot_host: str,
        ft_sensor: str,
        tracker: str | None,
        calibration: NetFTCalibration,
        servo: ServoParams,
        dry_run: bool,
        command_log_path: str | None,
        first_record_timeout_s: float = 2.0,
        servo_process: bool = False,
    ) -> CellDevices:
        """Connect everything; on any failure close what was opened and raise with what failed.

        ``command_log_path``: JSONL of every command (written where the link lives). ``servo_process``: open the
        link and the F/T stream in a servo process of their own (see the module docstring).
        """
        link: RobotLink | RemoteLink | None = None
        ft: NetFTClient | RemoteFT | None = None
        trk: Tracker | None = None
        process: ServoProcess | None = None
        host, port = split_host_port(ft_sensor, RDT_PORT)
        try:
            if servo_process:
                spec = ServoProcessSpec(
                    robot_host, servo, dry_run, command_log_path, (host, port), calibration,
                    first_record_timeout_s=first_record_timeout_s,
                )  # fmt: skip
                process = ServoProcess(spec)
                link, ft = RemoteLink(process), RemoteFT(process, calibration)
            else:
                link = RobotLink(robot_host, servo, dry_run, CommandLog(command_log_path))
                ft = NetFTClient(host, port, calibration)
                deadline = time.monotonic() + first_record_timeout_s
                while ft.latest() is None:
                    if time.monotonic() > deadline:
                        raise LinkError(
                            f"no record from the Net F/T at {host}:{port} within {first_record_timeout_s} s"
                        )
                    time.sleep(0.005)
            trk = make_tracker(tracker)
            return cls(link, ft, trk, process)
        except BaseException:
            for dev in (trk, ft, link):
                if dev is not None:
                    dev.close()
            raise

    def make_servo(
        self,
        ft_bias: np.ndarray,
        geometry: CellGeometry,
        path: DrillPath,
        limits: SafetyLimits,
        servo: ServoParams,
        force_limit_n: float,
        t0: float,
    ) -> Any:
        """One episode's servo loop, where the link lives (:class:`ServoLoop` or :class:`RemoteServo`)."""
        if self.process is not None:
            return RemoteServo(self.process, ft_bias, geometry, path, limits, servo, force_limit_n, t0)
        assert isinstance(self.link, RobotLink) and isinstance(self.ft, NetFTClient)
        return ServoLoop(self.link, self.ft, ft_bias, geometry, path, limits, servo, force_limit_n, t0)

    def tare(self, duration_s: float) -> tuple[np.ndarray, np.ndarray | None]:
        """F/T bias (N, N·m) and tracker marker position (m, base; None without readings): means over ``duration_s``."""
        t_start = time.monotonic()
        markers: dict[float, np.ndarray] = {}
        while time.monotonic() - t_start < duration_s:
            reading = self.tracker.latest()
            if reading is not None and reading.t_recv_s >= t_start:
                markers[reading.t_recv_s] = reading.position_base_m
            time.sleep(0.005)
        records = self.ft.since(t_start)
        if not records:
            raise LinkError(f"no F/T record for {duration_s} s while taring at the start pose")
        bias = np.mean([r.wrench for r in records], axis=0)
        return bias, (np.mean(list(markers.values()), axis=0) if markers else None)

    def close(self) -> None:
        """Close everything (the robot link last but one: it takes ``ur_rtde``'s 0.5 s per interface)."""
        self.tracker.close()
        self.ft.close()
        self.link.close()
