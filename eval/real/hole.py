"""One hole on the real cell (or the emulator), as ``drillgym run`` drills it: open the cell, drill, log, report.

:func:`open_cell` makes the real env for :class:`CellOptions` (the run's options that are the same for every hole),
a scenario and an entry point; :func:`drill_hole` drills one hole with it into ``<out>/logs/<name>`` (never replacing
a log: a run's record is append-only) and prints its measurable metrics, the servo loop's timing against the
machine's load (:mod:`drillgym.eval.real.load_report`) and, after a stale-stream or watchdog stop, its likely
cause; with ``record_rtde`` the hole is also a recording session for ``drillgym import-rtde``
(:func:`rtde_session`). :func:`summarise_dry_run` says how far a dry run's targets went.
"""

from __future__ import annotations

import contextlib
import json
import math
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym

from drillgym.controllers.rollout import run_episode
from drillgym.envs.cell_params import CellParams
from drillgym.envs.json_safe import json_safe
from drillgym.envs.real.config import SafetyLimits
from drillgym.envs.real.metrics import OBSERVABLE_METRICS
from drillgym.envs.real.netft import NetFTCalibration
from drillgym.eval.logs import EpisodeLogger, build_header, read_episode_log
from drillgym.eval.real.dry_run import describe_reach, target_reach
from drillgym.eval.real.load_report import describe_timing, likely_cause, servo_timing
from drillgym.eval.real.preflight import ENV_ID, seed_emulated_specimen
from drillgym.eval.real.record_session import RECORDING_MARGIN_S, RtdeFileRecorder, trim_recording, write_side_files


@dataclass(frozen=True)
class CellOptions:
    """How a run reaches and drives the cell, the same for each of its holes.

    ``robot``: the UR controller's address; ``ft``: the Net F/T's ``HOST[:PORT]`` (None: the robot's);
    ``tracker``: ``none`` or ``udp:HOST[:PORT]``; ``controller_spec`` as given (it names the logs); ``limits``: the
    safety limits (SI); ``servo_thread``: the servo loop as a thread of this process instead of its own process;
    ``record_rtde``: each hole also as a recording session; ``out``: the run's output folder.
    """

    robot: str
    ft: str | None
    tracker: str
    controller_spec: str
    dry_run: bool
    servo_thread: bool
    record_rtde: bool
    limits: SafetyLimits
    out: Path

    def log_name(self, suffix: str) -> str:
        """``real__<controller>__<suffix>.parquet``: a hole's log name (``suffix``: ``ep0``, or a plan's hole name)."""
        return f"real__{self.controller_spec.replace(':', '_').replace('/', '_')}__{suffix}.parquet"


def open_cell(
    opts: CellOptions,
    calibration: NetFTCalibration,
    commands: Path,
    scenario: dict[str, Any],
    cell_params: CellParams | None = None,
) -> gym.Env[Any, Any]:
    """The real env: ``commands`` logs every command, ``cell_params`` the registered entry point (None: default)."""
    return gym.make(
        ENV_ID,
        robot_host=opts.robot,
        ft_sensor=opts.ft,
        tracker=opts.tracker,
        ft_calibration=calibration,
        dry_run=opts.dry_run,
        command_log_path=str(commands),
        safety_limits=opts.limits,
        servo_process=not opts.servo_thread,
        cell_params=cell_params,
        **scenario,
    )


def write_metrics(out: Path, results: list[dict[str, Any]]) -> None:
    """``<out>/metrics.json``: one entry per hole drilled (or tried) so far."""
    (out / "metrics.json").write_text(json.dumps(json_safe(results), indent=2))


def print_metrics(metrics: dict[str, float]) -> None:
    """The metrics a real cell can measure, one a line (``n/a`` where there is no value)."""
    for name in OBSERVABLE_METRICS:
        value = metrics.get(name, math.nan)
        print(f"  {name:28s} {value:9.3f}" if math.isfinite(value) else f"  {name:28s}       n/a")
    print("  deviation_*_mm, hole_offset_mm: measure the hole on the specimen (no true tip on a real cell)")


def drill_hole(
    env: gym.Env[Any, Any],
    opts: CellOptions,
    controller: Any,
    seed: int,
    name: str,
    label: str,
    run_extra: dict[str, Any],
) -> tuple[dict[str, Any] | None, int]:
    """Drill one hole into ``<out>/logs/<name>`` and print how it went, under ``label`` (``hole 2 (A2) of 3``).

    ``run_extra`` goes into the log header's ``run`` entry. Returns the hole's ``metrics.json`` entry (None if it
    could not start) and its exit code: 0, 1 (could not start) or 3 (ended on a fault).
    """
    extra = {"controller_spec": opts.controller_spec, "robot": opts.robot, "dry_run": opts.dry_run, **run_extra}
    specimen = seed_emulated_specimen(opts.robot, seed)
    if specimen is not None:
        extra["emulator_specimen"] = specimen
    header = build_header(env, controller.describe(), seed, source="real", extra=extra)
    log = opts.out / "logs" / name
    logger = EpisodeLogger(env, log, header)  # never replaces a log: the record is append-only
    try:
        with rtde_session(opts, env, log, extra):
            try:
                info = run_episode(logger, controller, seed, keep_trace=False).info
            finally:
                logger.close_log()
    except RuntimeError as e:  # refused to start (safety bits, too far from the start pose, ...)
        print(f"{label}: could not start: {e}", file=sys.stderr)
        return None, 1
    metrics = dict(info.get("metrics") or {})
    timing = servo_timing(env)
    result = {
        "seed": seed,
        "log": f"logs/{name}",
        "failure": info.get("failure"),
        "error": info.get("error"),
        "metrics": metrics,
        "missed_cycles": info.get("missed_cycles"),
        "servo_timing": None if timing is None else timing.to_json(),
    }
    dry = " DRY RUN, nothing sent;" if opts.dry_run else ""
    print(f"{label} ({opts.controller_spec},{dry} log {log}):")
    code = 0
    if info.get("failure"):
        print(f"  ENDED ON A FAULT: {info['failure']}: {info['error']}; stop: {info.get('stop_result')}")
        code = 3
    print_metrics(metrics)
    if timing is not None:
        print(f"  {describe_timing(timing)}")
        cause = likely_cause(info.get("failure"), timing)
        if cause is not None:
            print(f"  likely cause: {cause}")
    return result, code


@contextlib.contextmanager
def rtde_session(opts: CellOptions, env: gym.Env[Any, Any], log: Path, run: dict[str, Any]) -> Iterator[None]:
    """With ``record_rtde``: record the episode run inside as a session for ``drillgym import-rtde``.

    ``ur_rtde``'s file recording of the robot state (a receive interface of its own) goes to
    ``<out>/rtde/<log name>/rtde.csv``; once the episode's log is closed, the recording is cut to the episode
    ± 0.5 s (whole lines, as the shipped session's generator does: the robot's approach before t0 is no part of
    the episode, and a busy start-up there can leave gaps the importer rightly refuses), and the F/T, tracker,
    commands and header files are written from the log, with the episode's t0 put on the RTDE clock.
    """
    if not opts.record_rtde:
        yield
        return

    session = opts.out / "rtde" / log.stem
    session.mkdir(parents=True, exist_ok=True)
    recorder = RtdeFileRecorder(opts.robot, session / "rtde.csv")
    try:
        yield
    finally:
        recorder.stop()
    header, frame = read_episode_log(log, allow_partial=True)
    t0 = env.unwrapped.streams.t0  # type: ignore[attr-defined]
    rtde_t0 = recorder.rtde_timestamp_at(t0)
    end_s = float(frame["t_s"].max()) if len(frame) else 0.0
    trim_recording(session / "rtde.csv", rtde_t0 - RECORDING_MARGIN_S, rtde_t0 + end_s + RECORDING_MARGIN_S)
    run = {**run, "rtde_clock_offset_s": round(recorder.offset_s, 6)}
    write_side_files(session, header, frame, rtde_t0, run)
    print(f"recording session for drillgym import-rtde: {session}")


def summarise_dry_run(env: gym.Env[Any, Any], commands: Path, out_json: Path) -> None:
    """A dry run: print how far the commanded targets (``commands``) went from the entry point; write ``out_json``."""
    cell = env.unwrapped
    try:
        reach = target_reach(commands, cell.T_base_task, cell.scenario.depth_m, cell.limits)  # type: ignore[attr-defined]
    except (OSError, ValueError) as e:
        print(f"DRY RUN: no reach summary: {e}", file=sys.stderr)
        return
    print(describe_reach(reach, commands))
    out_json.parent.mkdir(exist_ok=True)
    out_json.write_text(json.dumps(reach, indent=2))
