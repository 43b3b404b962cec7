"""The env's step in Python, on its objects, and what those objects show: the readable reference of the physics.

The compiled step (:mod:`drillgym.envs.compiled_step`) runs the same physics on the episode's named state; this one
runs on the env's Python objects (the cell and its tip balance, the path, the command queue, the sensors) and is
the step for unmodelled effects the kernel does not run (user effects, the sensor-side ones, every reality effect):
their hooks read and change those objects (:class:`drillgym.envs.effects.base.EffectHost`). The two agree within
rounding (``tests/envs/test_step_kernel.py``). Units SI; frames as named (base, task, sensor).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs.constants import (
    CONTROL_DT_S,
    MAX_EPISODE_STEPS,
    PHYSICS_DT_S,
    RTDE_RATE_HZ,
    SUBSTEPS_PER_STEP,
    TRACKER_RATE_HZ,
)
from drillgym.envs.drilling.contact import SampleRow
from drillgym.envs.effects.base import EffectStack
from drillgym.envs.observation import observation_of
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
)
from drillgym.envs.sensors import latest_sample_time_s
from drillgym.envs.task import Phase


def max_norm_exceeds(forces_n: np.ndarray, limit_n: float) -> bool:
    """Whether any row's Euclidean norm exceeds ``limit_n``: ``max(norm(rows)) > limit`` exactly, cheaply.

    The norm is computed (as ``np.linalg.norm(..., axis=1)``) only when the rows' largest component is
    within a factor √3 (rounded up) of the limit; below that no row can exceed it.
    """
    if float(np.abs(forces_n).max()) * 1.7320508075688774 * (1.0 + 1e-12) <= limit_n:
        return False
    return float(np.max(np.linalg.norm(forces_n, axis=1))) > limit_n


def advance(env: Any, corr: np.ndarray, scale: float) -> tuple[bool, bool]:
    """One agent step of physics for a checked action's correction (m, base frame) and feed scale (-).

    Sets ``env.step_deviation_m`` and ``env.step_lateral_n``; returns ``(terminated, truncated)``.
    """
    fx = env.effects
    delay_s = env.scenario.latency_s if fx is None else fx.command_delay_s(env, env.scenario.latency_s)
    env.pending.append((env.t_s + delay_s, corr, scale))  # unmodelled effects (envs.effects) may delay it
    sc = env.scenario
    rt = env.cell.R_base_task.T
    rtde_time = latest_sample_time_s(env.t_s + CONTROL_DT_S, RTDE_RATE_HZ)
    rec = env.recorder
    cell = env.cell
    offset, hook = (None, None) if fx is None else _effects_begin_step(env, fx)
    cell.begin_step(_chip_m(env), _advance_m(env))
    samples, times, phases, depths = _run_samples(env, rt, offset, hook, rtde_time)
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
        wrenches = fx.sensor_wrenches(env, wrenches, rows[:, OUT_T_S].copy())
    readings = env.ft.sample_block(wrenches)
    forces = readings[:, :3]
    rows[:, OUT_FORCE : OUT_TORQUE + 3] = readings
    if env.failure is None and max_norm_exceeds(forces, sc.force_limit_n):
        env.failure = "force_limit"
    if rtde_time >= env.t_s - 1e-12:
        env.rtde_tcp_base = cell.tcp_rtde_base_m()
    env.ft_last = readings[-1]
    env.ft_mean = np.add.reduce(readings, axis=0) / SUBSTEPS_PER_STEP  # readings.mean(axis=0), bit for bit
    env.cell.end_step()
    _sample_tracker(env)
    rows[:, OUT_TRACKER_DEVIATION] = env.tracker_lateral_m
    env.step_deviation_m = sum(deviations) / SUBSTEPS_PER_STEP
    env.step_lateral_n = sum(math.hypot(f[0], f[1]) for _, _, f, *_ in samples) / SUBSTEPS_PER_STEP
    terminated = env.path.phase == Phase.DONE or env.failure is not None
    env.steps += 1
    at_limit = env.t_s >= env.max_time_s or env.steps >= MAX_EPISODE_STEPS
    truncated = env.truncated = (not terminated) and at_limit
    if terminated or truncated:
        env.metrics = env.episode_metrics()
    return terminated, truncated


def _run_samples(
    env: Any, rt: np.ndarray, offset: tuple[float, float, float] | None, hook: Any, rtde_time: float
) -> tuple[list[SampleRow], list[float], list[int], list[float]]:
    """The step's F/T samples: tip balance rows, their times (s), path phases and commanded depths (m).

    The samples' servo targets follow the path and the queued commands, not the physics: they are
    collected first and the tip balance runs over them in one pass, cut where a feed change
    re-prepares the balance (the order of every operation is that of one sample after the other).
    """
    cell, path, pending = env.cell, env.path, env.pending
    cx, cy, cz = _servo_xyz(env, rt, offset)
    times: list[float] = []
    phases: list[int] = []
    depths: list[float] = []
    targets: list[tuple[float, float, float]] = []
    samples: list[SampleRow] = []
    rtde_k = -1
    t_s = env.t_s
    for k in range(SUBSTEPS_PER_STEP):
        t_next = t_s + PHYSICS_DT_S
        while pending and pending[0][0] <= t_next + 1e-12:
            _, env.correction_base_m, scale = pending.popleft()
            if scale != env.feed_scale:
                samples += cell.run(targets[len(samples) :])
                env.feed_scale = scale
                env.t_s = t_s  # _advance_m reads the time of this sample
                cell.begin_step(_chip_m(env), _advance_m(env))
            cx, cy, cz = _servo_xyz(env, rt, offset)
        phase = path.phase
        s = path.advance(PHYSICS_DT_S, env.feed_scale)
        if t_s <= rtde_time < t_next:
            rtde_k = k
        targets.append((cx, cy, cz + s) if hook is None else hook(t_next, (cx, cy, cz + s)))
        times.append(t_next)
        phases.append(phase.value)
        depths.append(s)
        t_s = t_next
    samples += cell.run(targets[len(samples) :])
    env.t_s = t_s
    if rtde_k >= 0:  # the RTDE sample saw the servo-held tip before sample rtde_k
        env.rtde_tcp_base = cell.tcp_rtde_base_m(samples[rtde_k - 1][1] if rtde_k > 0 else None)
    return samples, times, phases, depths


def _effects_begin_step(env: Any, fx: EffectStack) -> tuple[tuple[float, float, float] | None, Any]:
    """Run the effects' step-start hooks; their servo/geometry offset (m, task frame) and target hook."""
    fx.begin_step(env)
    return fx.target_offset_task_m(env.cell.geometry_offset_task_m), fx.target_hook


def _servo_xyz(env: Any, rt: np.ndarray, offset: tuple[float, float, float] | None) -> list[float]:
    """Commanded correction in the task frame (m), plus the effects' servo/geometry offset if any."""
    xyz = (rt @ env.correction_base_m).tolist()
    if offset is not None:
        xyz = [xyz[0] + offset[0], xyz[1] + offset[1], xyz[2] + offset[2]]
    return xyz


def _advance_m(env: Any) -> float:
    """Axial advance of the commanded tip per physics update over this step (m): feed plus correction.

    The drill cuts sideways in proportion to how far it advances, so a correction that plunges the
    tip along its axis counts as advance too (the lateral cut resistance is per metre of advance).
    """
    corr_now = env.correction_base_m
    corr_end = corr_now
    for t_apply, corr, _ in env.pending:
        if t_apply <= env.t_s + CONTROL_DT_S + 1e-12:
            corr_end = corr
    dz_corr = 0.0 if corr_end is corr_now else float(env.cell.R_base_task[:, 2] @ (corr_end - corr_now))
    per_step = env.path.speed_m_s(env.feed_scale) * CONTROL_DT_S + dz_corr
    return max(per_step / SUBSTEPS_PER_STEP, 0.0)


def _chip_m(env: Any) -> float:
    """Chip thickness per lip (m) at the feed in force and the spindle's speed now (``cell.spindle_rpm``)."""
    sc = env.scenario
    return sc.geometry.chip_thickness_m(sc.feed_m_s * env.feed_scale, env.cell.spindle_rpm)


def _sample_tracker(env: Any) -> None:
    stamp = latest_sample_time_s(env.t_s, TRACKER_RATE_HZ)
    if stamp != env.tracker_stamp:
        env.tracker_stamp = stamp
        marker = env.cell.marker_base_m()
        if env.effects is not None:
            marker = env.effects.tracker_marker_base_m(env, marker, stamp)
        env.tracker_reading = env.tracker.sample(marker)
    planned = env.marker_start_base + env.cell.R_base_task @ np.array([0.0, 0.0, env.path.s_m - env.s_start_m])
    env.tracker_error_base = env.tracker_reading - planned
    lateral = env.cell.R_base_task.T @ env.tracker_error_base
    env.tracker_lateral_m = math.hypot(lateral[0], lateral[1])


def _nominal_tcp_base(env: Any) -> np.ndarray:
    return env.cell.entry_base_m + env.cell.R_base_task @ np.array([0.0, 0.0, env.path.s_m])


def observation(env: Any) -> dict[str, np.ndarray]:
    """The observation from the env's objects (:func:`drillgym.envs.observation.observation_of`)."""
    tracking = len(env.recorder) > 0 and env.scenario.tracker
    return observation_of(
        env.ft_last,
        env.ft_mean,
        env.cell.q_motor_rad,
        env.rtde_tcp_base - _nominal_tcp_base(env),
        env.tracker_error_base if tracking else 0.0,
        1.0 if env.scenario.tracker else 0.0,
        env.path.s_m,
        int(env.path.phase),
        env.correction_base_m,
        env.feed_scale,
    )


def info(env: Any) -> dict[str, Any]:
    """The step's info from the env's objects: the privileged state, the reward's terms and the failure."""
    smp = env.cell.sample
    info: dict[str, Any] = {
        "t_s": env.t_s,
        "phase": int(env.path.phase),
        "stage": smp.stage,
        "depth_cmd_m": env.path.s_m,
        "tip_pos_task_m": np.array(smp.tip),
        "deviation_m": math.hypot(smp.tip[0], smp.tip[1]),
        "tip_deflection_robot_m": env.cell.tip_deflection_robot_m(),
        "tip_deflection_tool_m": env.cell.tip_deflection_tool_m(),
        "force_true_n": np.array(smp.force),
        "depth_local_m": smp.depth_local,
        "reward_terms": dict(env.step_terms),
        "failure": env.failure,
        "specimen_hardness": env.specimen_hardness,
    }
    if env.metrics is not None:
        info["metrics"] = dict(env.metrics)
        info["metrics_truncated"] = env.truncated
    return info
