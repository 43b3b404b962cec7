"""The real cell's devices, opened together and closed together: robot link, F/T sensor, tracker."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from drillgym.envs.real.command_log import CommandLog
from drillgym.envs.real.config import ServoParams
from drillgym.envs.real.netft import RDT_PORT, NetFTCalibration, NetFTClient
from drillgym.envs.real.robot_link import LinkError, RobotLink
from drillgym.envs.real.tracker import Tracker, make_tracker


def split_host_port(spec: str, default_port: int) -> tuple[str, int]:
    """``"HOST"`` or ``"HOST:PORT"`` -> ``(host, port)``."""
    host, _, port = spec.partition(":")
    if not host:
        raise ValueError(f"{spec!r} does not name a host")
    return host, int(port) if port else default_port


@dataclass
class CellDevices:
    """Open connections to the robot, the F/T sensor and the tracker."""

    link: RobotLink
    ft: NetFTClient
    tracker: Tracker

    @classmethod
    def open(
        cls,
        robot_host: str,
        ft_sensor: str,
        tracker: str | None,
        calibration: NetFTCalibration,
        servo: ServoParams,
        dry_run: bool,
        command_log: CommandLog,
        first_record_timeout_s: float = 2.0,
    ) -> CellDevices:
        """Connect everything; on any failure close what was opened and raise with what failed."""
        link: RobotLink | None = None
        ft: NetFTClient | None = None
        trk: Tracker | None = None
        try:
            link = RobotLink(robot_host, servo, dry_run, command_log)
            host, port = split_host_port(ft_sensor, RDT_PORT)
            ft = NetFTClient(host, port, calibration)
            deadline = time.monotonic() + first_record_timeout_s
            while ft.latest() is None:
                if time.monotonic() > deadline:
                    raise LinkError(f"no record from the Net F/T at {host}:{port} within {first_record_timeout_s} s")
                time.sleep(0.005)
            trk = make_tracker(tracker)
            return cls(link, ft, trk)
        except BaseException:
            for dev in (trk, ft, link):
                if dev is not None:
                    dev.close()
            raise

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
