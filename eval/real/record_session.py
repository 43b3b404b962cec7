"""Write a real-cell recording session (the folder ``drillgym import-rtde`` reads) while an episode runs.

The robot state is recorded by ``ur_rtde`` itself: a receive interface of its own, beside the env's, with
``RTDEReceiveInterface.startFileRecording(path, RECORDED_VARIABLES)`` (:class:`RtdeFileRecorder`). Its
timestamps count from the controller's start; the episode clock is the host's ``time.monotonic()`` from the
stream's start, so the recorder estimates the controller-minus-host clock offset from ``getTimestamp()``
read against ``time.monotonic()`` (the freshest of many reads; on loopback it is off by a few ms at most, on
a cell by the network latency) and the header's ``clock.rtde_timestamp_at_t0_s`` is the episode's ``t0``
plus that offset. The other files come from the episode's log (:func:`write_side_files`): ``ft.csv`` holds the
env's 100 Hz F/T samples (10 ms bin means of the sensor's records, tared, sensor frame), ``tracker.csv`` the
marker as the env read it at the end of each agent step, ``commands.csv`` each step's command at the start of
its window (when the env applied it).

The shipped test session ``tests/data/rtde_session_emulator/`` was made with this module against the emulator:

    .venv/bin/python -m drillgym.eval.real.record_session tests/data/rtde_session_emulator \
        --log tests/data/rtde_session_emulator_env_log.parquet

(:func:`record_emulator_session`: a shallow li2023 hole, 3 mm at 3 mm/s, seed 0, about 4 s of episode).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pandas as pd

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode
from drillgym.envs.constants import CONTROL_DT_S
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.emulator.process import EmulatorProcess
from drillgym.eval.diagnosis.rtde_import import import_session
from drillgym.eval.logs import EpisodeLogger, build_header, read_episode_log
from drillgym.eval.real.preflight import ENV_ID, seed_emulated_specimen

RECORDED_VARIABLES = ("timestamp", "actual_q", "actual_TCP_pose")
"""What the importer needs from the robot (``ur_rtde`` expands a vector as ``name_0 … name_{n-1}``)."""


class RtdeFileRecorder:
    """``ur_rtde``'s own file recording of the robot state, on a receive interface of its own.

    Args:
        host: the UR controller (or emulator) address.
        path: the CSV file ``startFileRecording`` writes.
        frequency_hz: the RTDE output rate asked for (125 Hz: every CB3 controller cycle).
    """

    def __init__(self, host: str, path: str | Path, frequency_hz: float = 125.0) -> None:
        import rtde_receive

        self.path = Path(path)
        self.receive = rtde_receive.RTDEReceiveInterface(host, frequency_hz, list(RECORDED_VARIABLES))
        self.offset_s = self._clock_offset()
        if not self.receive.startFileRecording(str(self.path), list(RECORDED_VARIABLES)):
            self.receive.disconnect()
            raise OSError(f"ur_rtde could not start recording to {self.path}")

    def _clock_offset(self, reads: int = 200) -> float:
        """RTDE timestamp minus ``time.monotonic()`` (s).

        The largest difference over ``reads`` reads, 1 ms apart: a state read late makes it smaller, never larger.
        """
        best = -np.inf
        for _ in range(reads):
            best = max(best, float(self.receive.getTimestamp()) - time.monotonic())
            time.sleep(1e-3)
        return float(best)

    def rtde_timestamp_at(self, t_monotonic: float) -> float:
        """The controller's RTDE timestamp at a host ``time.monotonic()`` instant."""
        return t_monotonic + self.offset_s

    def stop(self) -> None:
        """Stop recording (the file is flushed and closed) and disconnect."""
        try:
            self.receive.stopFileRecording()
        finally:
            self.receive.disconnect()


def write_side_files(
    d: Path, header: dict[str, Any], frame: pd.DataFrame, rtde_timestamp_at_t0_s: float, run: dict[str, Any]
) -> None:
    """Write ``ft.csv``, ``tracker.csv``, ``commands.csv`` and ``header.json`` of a session from an episode log.

    ``header``, ``frame``: as :func:`drillgym.eval.logs.read_episode_log` returns them; ``t_s`` is the episode
    clock (``host_t0_s`` 0).
    """
    ft = pd.DataFrame({"t_s": frame["t_s"]})
    for axis, column in zip(
        ("fx_n", "fy_n", "fz_n", "tx_nm", "ty_nm", "tz_nm"),
        ("ft_fx_n", "ft_fy_n", "ft_fz_n", "ft_tx_nm", "ft_ty_nm", "ft_tz_nm"),
        strict=True,
    ):
        ft[axis] = frame[column]
    ft.to_csv(d / "ft.csv", index=False, float_format="%.6f")
    step = frame["step"].to_numpy()
    first = np.flatnonzero(np.diff(np.concatenate([[-1], step])) != 0)
    last = np.append(first[1:] - 1, len(frame) - 1)
    steps = step[first]
    tracker = pd.DataFrame({"t_s": (steps + 1) * CONTROL_DT_S})
    for a in "xyz":
        tracker[f"{a}_m"] = frame[f"tracker_{a}_base_m"].to_numpy()[last]
    tracker["valid"] = frame["tracker_valid"].to_numpy()[last].astype(int)
    tracker.to_csv(d / "tracker.csv", index=False, float_format="%.7f")
    commands = pd.DataFrame({"t_s": steps * CONTROL_DT_S, "phase": frame["phase"].to_numpy()[first]})
    commands["depth_cmd_m"] = frame["depth_cmd_m"].to_numpy()[first]
    for name in ("cmd_dx_base_m", "cmd_dy_base_m", "cmd_dz_base_m", "cmd_feed_scale"):
        commands[name] = frame[name].to_numpy()[first]
    commands.to_csv(d / "commands.csv", index=False, float_format="%.9g")
    meta = {
        "scenario": header["scenario"],
        "controller": header.get("controller"),
        "plan": header.get("plan", {}),
        "versions": header.get("versions", {}),
        "created_utc": header.get("created_utc"),
        "clock": {"rtde_timestamp_at_t0_s": round(rtde_timestamp_at_t0_s, 6), "host_t0_s": 0.0},
        "run": run,
    }
    (d / "header.json").write_text(json.dumps(meta, indent=1, default=_json_default) + "\n")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON: {type(value).__name__}")


RECORDING_MARGIN_S = 0.5
"""A session's RTDE recording is kept from this long before the episode's t0 to this long after its last step (s)."""


def trim_recording(path: Path, t_from: float, t_to: float) -> int:
    """Keep the header line and the rows with ``t_from <= timestamp <= t_to``; returns the rows kept.

    Every kept line stays as ``ur_rtde`` wrote it.
    """
    lines = path.read_text().splitlines()
    kept = [line for line in lines[1:] if t_from <= float(line.split(",", 1)[0]) <= t_to]
    path.write_text("\n".join([lines[0], *kept]) + "\n")
    return len(kept)


def record_emulator_session(
    out: Path,
    scenario: dict[str, Any] | None = None,
    controller_spec: str = "li2023",
    seed: int = 0,
    margin_s: float = RECORDING_MARGIN_S,
    log_path: Path | None = None,
) -> Path:
    """Drill one hole on an emulator of its own (random loopback address) and write its session to ``out``.

    The RTDE recording is trimmed to the episode ± ``margin_s`` (the move to the start pose and the tare before
    it are left out, to keep the folder small). ``log_path``: keep the env's own episode log of the run there
    (to compare the import with). Returns ``out``.

    Raises:
        LogCheckError: the session fails the importer's checks, e.g. the recording missed robot states on a busy
            machine (``ur_rtde`` keeps the newest state it reads); delete ``out`` and run it again.
    """
    scenario = dict(scenario or {"feed_mm_s": 3.0, "depth_mm": 3.0})
    out.mkdir(parents=True, exist_ok=False)
    controller = make_controller(controller_spec)
    limits = SafetyLimits(max_cycle_gap_s=0.5, rtde_stale_s=0.5, ft_stale_s=0.5, tracker_stale_s=0.5)
    keep_log = log_path is not None
    log_path = log_path or out / "episode.parquet"
    with EmulatorProcess(scenario=scenario, seed=seed, max_lifetime_s=120.0) as emu:
        recorder = RtdeFileRecorder(emu.host, out / "rtde.csv")
        try:
            env = gym.make(ENV_ID, robot_host=emu.host, tracker=f"udp:{emu.host}", safety_limits=limits, **scenario)
            try:
                specimen = seed_emulated_specimen(emu.host, seed)
                extra = {"controller_spec": controller_spec, "robot": "emulator", "emulator_specimen": specimen}
                header = build_header(env, controller.describe(), seed, source="real", extra=extra)
                logger = EpisodeLogger(env, log_path, header, overwrite=True)
                try:
                    info = run_episode(logger, controller, seed, keep_trace=False).info
                finally:
                    logger.close_log()
                t0 = env.unwrapped.streams.t0  # type: ignore[attr-defined]
            finally:
                env.close()
        finally:
            recorder.stop()
    if info.get("failure"):
        raise RuntimeError(f"the episode ended on {info['failure']}: {info.get('error')}")
    header, frame = read_episode_log(log_path)
    if not keep_log:
        log_path.unlink()
    rtde_t0 = recorder.rtde_timestamp_at(t0)
    end_s = float(frame["t_s"].max()) + CONTROL_DT_S
    rows = trim_recording(out / "rtde.csv", rtde_t0 - margin_s, rtde_t0 + end_s + margin_s)
    run = {
        "recorded_by": "drillgym.eval.real.record_session.record_emulator_session",
        "robot": "drillgym emulate (loopback)",
        "controller_spec": controller_spec,
        "seed": seed,
        "emulator_specimen": header.get("run", {}).get("emulator_specimen"),
        "rtde_clock_offset_s": round(recorder.offset_s, 6),
        "rtde_rows_kept": rows,
        "rtde_trimmed_to_episode_s": margin_s,
        "metrics": {k: v for k, v in (info.get("metrics") or {}).items() if np.isfinite(v)},
    }
    write_side_files(out, header, frame, rtde_t0, run)

    import_session(out)  # the importer's checks: a recording with a gap (a busy machine) raises LogCheckError
    return out


def main(argv: list[str] | None = None) -> int:
    """``python -m drillgym.eval.real.record_session OUT``: a shallow hole on an emulator, as a session folder."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", type=Path, help="session folder to create (must not exist)")
    parser.add_argument("--controller", default="li2023")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--log", type=Path, default=None, help="also keep the env's own episode log here")
    args = parser.parse_args(argv)
    out = record_emulator_session(args.out, controller_spec=args.controller, seed=args.seed, log_path=args.log)
    print(f"session in {out}: " + ", ".join(f"{p.name} {p.stat().st_size} B" for p in sorted(out.iterdir())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
