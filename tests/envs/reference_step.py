"""A frozen copy of the env step as it was before the speed work (commit 7aa0587), for equivalence tests.

Everything an agent step computes (the tip balance per F/T sample, the sensors, the IK/compliance
refresh, the tracker, the observation and the info) is re-implemented here in the original, slow
per-sample form, on the state of a live :class:`drillgym.envs.drill_env.UR5BoneDrillEnv`. A test steps
one env with ``env.step`` and a twin with :func:`reference_step` and requires every observation, reward
and info entry to be bit for bit the same. Do not optimise this file: it is the yardstick.
Caches it keeps on the solver are named ``_ref_*`` so they never mix with the fast path's.
"""

from __future__ import annotations

import bisect
import math
from typing import Any

import numpy as np
import pinocchio as pin

from drillgym.envs.constants import (
    ACTION_DIM,
    CONTROL_DT_S,
    FT_RESOLUTION,
    MAX_EPISODE_STEPS,
    PHYSICS_DT_S,
    RTDE_RATE_HZ,
    SUBSTEPS_PER_STEP,
    TRACKER_RATE_HZ,
    scale_action,
)
from drillgym.envs.drilling.contact import ContactSample
from drillgym.envs.drilling.force_model import stage_of
from drillgym.envs.observation import OBS_BOUNDS
from drillgym.envs.robot.ur5 import R_BASE_BASELINK, TCP_FRAME, TRACKER_FRAME
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

# ---------------------------------------------------------------------- kinematics (envs/robot/ur5.py)


def _se3_to_base(m: Any) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = R_BASE_BASELINK @ m.rotation
    t[:3, 3] = R_BASE_BASELINK @ m.translation
    return t


def _fk(kin: Any, q_rad: np.ndarray, frame: str) -> np.ndarray:
    pin.framesForwardKinematics(kin.model, kin.data, np.asarray(q_rad, dtype=float))
    return _se3_to_base(kin.data.oMf[kin.frame_ids[frame]])


def _jacobian(kin: Any, q_rad: np.ndarray, frame: str) -> np.ndarray:
    q = np.asarray(q_rad, dtype=float)
    j = pin.computeFrameJacobian(kin.model, kin.data, q, kin.frame_ids[frame], pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    out = np.empty((6, 6))
    out[:3] = R_BASE_BASELINK @ j[:3]
    out[3:] = R_BASE_BASELINK @ j[3:]
    return out


def _pose_error(kin: Any, q_rad: np.ndarray, T_base_target: np.ndarray, frame: str) -> np.ndarray:
    t = _fk(kin, q_rad, frame)
    dp = T_base_target[:3, 3] - t[:3, 3]
    dr = pin.log3(T_base_target[:3, :3] @ t[:3, :3].T)
    return np.concatenate([dp, dr])


# ---------------------------------------------------------------------- tip balance (envs/drilling/contact.py)


def _inv3(a: np.ndarray) -> np.ndarray:
    (a00, a01, a02), (a10, a11, a12), (a20, a21, a22) = a.tolist()
    c00 = a11 * a22 - a12 * a21
    c01 = a12 * a20 - a10 * a22
    c02 = a10 * a21 - a11 * a20
    det = a00 * c00 + a01 * c01 + a02 * c02
    return (
        np.array(
            [
                [c00, a02 * a21 - a01 * a22, a01 * a12 - a02 * a11],
                [c01, a00 * a22 - a02 * a20, a02 * a10 - a00 * a12],
                [c02, a01 * a20 - a00 * a21, a00 * a11 - a01 * a10],
            ]
        )
        / det
    )


def _prepare(sv: Any, compliance_m_n: np.ndarray, chip_m: float, advance_per_update_m: float) -> None:
    rows = sv.force_scale * (sv.table.edge + chip_m * sv.table.per_chip)
    if sv.depth_profile is not None:
        rows = rows * sv.depth_profile[:, None]
    sv._ref_fx, sv._ref_fy, sv._ref_fz, sv._ref_mz = (rows[:, i].tolist() for i in range(4))
    sv._ref_c = np.asarray(compliance_m_n, dtype=float)
    share = float(np.interp(sv.depth_local, sv.table.depth_m, sv.table.engaged_fraction))
    if sv.wall_floor >= 1.0:
        wall_factor = 1.0
    else:
        wall = min(max((sv.depth_local - sv._bounds[3]) / sv.wall_length_m, 0.0), 1.0)
        wall_factor = sv.wall_floor + (1.0 - sv.wall_floor) * wall
    sv._ref_g = share**sv.guidance_exponent * wall_factor
    if sv.entry_guidance != 0.0 and share < 1.0:  # skid friction (once a guidance hook)
        sv._ref_g = sv._ref_g + sv.entry_guidance * (1.0 - share)
    if sv.guidance_hook is not None:
        sv._ref_g = sv.guidance_hook(share, sv._ref_g)
    sv._ref_k_cut = sv.k_lat_n / max(advance_per_update_m, 1e-7)
    sv._ref_variants = {}


def _variant(sv: Any, v: int) -> tuple:
    if v not in sv._ref_variants:
        k, g = sv._ref_k_cut, sv._ref_g
        kx, ky = ((0.0, 0.0), (k * g, k * g))[v]
        kc = np.diag([kx, ky, 0.0])
        m = _inv3(np.eye(3) + sv._ref_c @ kc)
        s = m @ sv._ref_c
        mck = s @ kc
        sv._ref_variants[v] = (m.tolist(), s.tolist(), mck.tolist(), (kx, ky))
    return sv._ref_variants[v]


def _row(sv: Any, d: float) -> tuple[tuple[float, float, float], float]:
    grid = sv.grid
    n = len(grid)
    if d <= grid[0]:
        j, t = 1, 0.0
    elif d >= grid[-1]:
        j, t = n - 1, 1.0
    else:
        j = bisect.bisect_right(grid, d)
        t = (d - grid[j - 1]) / (grid[j] - grid[j - 1])
    fx, fy, fz, mz = sv._ref_fx, sv._ref_fy, sv._ref_fz, sv._ref_mz
    a = j - 1
    return (
        (fx[a] + t * (fx[j] - fx[a]), fy[a] + t * (fy[j] - fy[a]), fz[a] + t * (fz[j] - fz[a])),
        mz[a] + t * (mz[j] - mz[a]),
    )


def _solve_depth(sv: Any, front_z: float, base_x: float, s_x: list[float]) -> float:
    tb = sv.tan_beta
    rhs = front_z + tb * base_x
    if tb == 0.0:
        return rhs
    fx, fy, fz = sv._ref_fx, sv._ref_fy, sv._ref_fz
    a, b, c = s_x

    def q(i: int) -> float:
        return a * fx[i] + b * fy[i] + c * fz[i]

    grid = sv.grid
    n = len(grid)
    j = min(max(sv._j, 1), n - 1)
    for _ in range(4 * n):
        d0, d1 = grid[j - 1], grid[j]
        h0 = d0 - tb * q(j - 1) - rhs
        h1 = d1 - tb * q(j) - rhs
        if h0 > 0.0:
            if j == 1:
                sv._j = 1
                return rhs + tb * q(0)
            j -= 1
        elif h1 < 0.0:
            if j == n - 1:
                sv._j = j
                return rhs + tb * q(n - 1)
            j += 1
        else:
            sv._j = j
            return d0 + (d1 - d0) * (-h0) / (h1 - h0) if h1 != h0 else d0
    raise RuntimeError("tip balance: no stable root found")


def _update(sv: Any, target: tuple[float, float, float], servo_gain: float) -> ContactSample:
    r = sv.rigid
    for i in range(3):
        r[i] += servo_gain * (target[i] - r[i])
    prev = sv.tip
    inside = prev[2] + prev[0] * sv.tan_beta > sv._bounds[0]
    v = 1 if sv.touching and inside else 0
    m, s, mck, (kx, ky) = _variant(sv, v)
    base = [
        m[i][0] * r[0] + m[i][1] * r[1] + m[i][2] * r[2] + mck[i][0] * prev[0] + mck[i][1] * prev[1] for i in range(3)
    ]
    front = max(sv.bottom_z, prev[2])
    d = _solve_depth(sv, front, base[0], s[0])
    f, torque = _row(sv, d)
    touching = f[0] != 0.0 or f[1] != 0.0 or f[2] != 0.0
    sf = [s[i][0] * f[0] + s[i][1] * f[1] + s[i][2] * f[2] for i in range(3)]
    full_z = base[2] + sf[2]
    if not touching or full_z >= sv.bottom_z:
        lam = 1.0
    elif base[2] > sv.bottom_z:
        lam = (base[2] - sv.bottom_z) / (base[2] - full_z)
    else:
        lam = 0.0
    tip = [base[i] + lam * sf[i] for i in range(3)]
    force = [lam * f[0] + kx * (prev[0] - tip[0]), lam * f[1] + ky * (prev[1] - tip[1]), lam * f[2]]
    cutting = touching and lam >= 1.0 and tip[2] > sv.bottom_z
    if cutting:
        sv.bottom_z = tip[2]
        sv.hole.record(tip[2], np.array(tip[:2]))
    sv.tip = tip
    sv.force = force
    sv.torque = lam * torque
    sv.depth_local = d
    sv.touching = touching
    stage = stage_of(d, sv._bounds) if touching and lam > 0.0 else 0
    return ContactSample(
        (tip[0], tip[1], tip[2]), (r[0], r[1], r[2]), (force[0], force[1], force[2]), sv.torque, d, stage, cutting
    )


# ---------------------------------------------------------------------- cell (envs/cell.py)


def _tip_pose_base(cell: Any, tip_task_m: np.ndarray) -> np.ndarray:
    t = cell.T_base_task.copy()
    t[:3, 3] = cell.entry_base_m + cell.R_base_task @ tip_task_m
    return t


def _update_compliance(cell: Any) -> None:
    j = _jacobian(cell.kin, cell.q_motor_rad, TCP_FRAME)
    cell.J_tcp = j
    jv = j[:3]
    c_base = (jv / cell.joints.stiffness_nm_rad) @ jv.T
    cell.C_robot = cell.R_base_task.T @ c_base @ cell.R_base_task
    cell.C_total = cell.C_robot + cell.C_tool


def _end_step(cell: Any) -> None:
    rigid = np.asarray(cell.sample.rigid)
    if cell.geometry_offset_task_m is not None:
        rigid = rigid - cell.geometry_offset_task_m
    target = _tip_pose_base(cell, rigid)
    err = _pose_error(cell.kin, cell.q_motor_rad, target, TCP_FRAME)
    cell.q_motor_rad = cell.q_motor_rad + np.linalg.solve(cell.J_tcp, err)
    _update_compliance(cell)


def _tcp_rtde_base_m(cell: Any) -> np.ndarray:
    rigid_tip = np.asarray(cell.sample.rigid)
    if cell.geometry_offset_task_m is not None:
        return cell.entry_base_m + cell.R_base_task @ (rigid_tip - cell.geometry_offset_task_m)
    return cell.entry_base_m + cell.R_base_task @ rigid_tip


def _marker_base_m(cell: Any) -> np.ndarray:
    force = np.asarray(cell.sample.force)
    w = np.concatenate([cell.R_base_task @ force, cell.R_base_task @ np.array([0.0, 0.0, cell.sample.torque_axis])])
    dq = (cell.J_tcp.T @ np.asarray(w, dtype=float)) / cell.joints.stiffness_nm_rad
    p = _fk(cell.kin, cell.q_motor_rad + dq, TRACKER_FRAME)[:3, 3]
    return p if cell.marker_offset_base_m is None else p + cell.marker_offset_base_m


# ---------------------------------------------------------------------- env (envs/drill_env.py, sensors, observation)


def _sample_block(ft: Any, wrenches_sensor: np.ndarray) -> np.ndarray:
    w = np.asarray(wrenches_sensor, dtype=float)
    if ft.noise_n > 0:
        w = w + ft._noise_std * ft.rng.standard_normal(w.shape)
    return np.round(w / FT_RESOLUTION) * FT_RESOLUTION


def _tracker_sample(tracker: Any, position_m: np.ndarray) -> np.ndarray:
    if tracker.noise_m <= 0:
        return np.asarray(position_m, dtype=float).copy()
    return position_m + tracker.noise_m * tracker.rng.standard_normal(3)


_KEYS = tuple(OBS_BOUNDS)
_SIZES = [n for n, _ in OBS_BOUNDS.values()]
_OFFSETS = np.cumsum([0, *_SIZES])
_NONNEG = ("tracker_valid", "phase", "feed_scale")
_HI = np.concatenate([np.full(n, b) for n, b in OBS_BOUNDS.values()])
_LO = np.concatenate([np.full(n, 0.0 if k in _NONNEG else -b) for k, (n, b) in OBS_BOUNDS.items()])


def _pack_observation(values: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    flat = np.concatenate([np.ravel(values[k]) for k in _KEYS])
    flat = np.clip(flat, _LO, _HI).astype(np.float32)
    return {k: flat[_OFFSETS[i] : _OFFSETS[i + 1]] for i, k in enumerate(_KEYS)}


def _servo_xyz(env: Any, rt: np.ndarray, offset: tuple[float, float, float] | None) -> list[float]:
    xyz = (rt @ env.correction_base_m).tolist()
    if offset is not None:
        xyz = [xyz[0] + offset[0], xyz[1] + offset[1], xyz[2] + offset[2]]
    return xyz


def _advance_m(env: Any) -> float:
    corr_now = env.correction_base_m
    corr_end = corr_now
    for t_apply, corr, _ in env.pending:
        if t_apply <= env.t_s + CONTROL_DT_S + 1e-12:
            corr_end = corr
    dz_corr = float(env.cell.R_base_task[:, 2] @ (corr_end - corr_now))
    per_step = env.path.speed_m_s(env.feed_scale) * CONTROL_DT_S + dz_corr
    return max(per_step / SUBSTEPS_PER_STEP, 0.0)


def _chip_m(env: Any) -> float:
    sc = env.scenario  # the spindle's speed now: the scenario's unless an effect (spindle sag) changed it
    return sc.geometry.chip_thickness_m(sc.feed_m_s * env.feed_scale, env.cell.spindle_rpm)


def _begin_step(env: Any) -> None:
    _prepare(env.cell.solver, env.cell.C_total, _chip_m(env), _advance_m(env))


def _sample_tracker(env: Any) -> None:
    cell = env.cell
    stamp = latest_sample_time_s(env.t_s, TRACKER_RATE_HZ)
    if stamp != env.tracker_stamp:
        env.tracker_stamp = stamp
        marker = _marker_base_m(cell)
        if env.effects is not None:  # effects that move what the tracker reports (e.g. a late tracker)
            marker = env.effects.tracker_marker_base_m(env, marker, stamp)
        env.tracker_reading = _tracker_sample(env.tracker, marker)
    planned = env.marker_start_base + cell.R_base_task @ np.array([0.0, 0.0, env.path.s_m - env.s_start_m])
    env.tracker_error_base = env.tracker_reading - planned
    lateral = cell.R_base_task.T @ env.tracker_error_base
    env.tracker_lateral_m = math.hypot(lateral[0], lateral[1])


def reference_observation(env: Any) -> dict[str, np.ndarray]:
    """The observation as the original ``_observation`` packed it."""
    if len(env.recorder):
        tracker_err = env.tracker_error_base if env.scenario.tracker else np.zeros(3)
    else:
        tracker_err = np.zeros(3)
    phase = np.zeros(3)
    phase[min(int(env.path.phase), 2)] = 1.0
    nominal = env.cell.entry_base_m + env.cell.R_base_task @ np.array([0.0, 0.0, env.path.s_m])
    return _pack_observation(
        {
            "ft_wrench": env.ft_last,
            "ft_wrench_mean": env.ft_mean,
            "q_rad": env.cell.q_motor_rad,
            "tcp_error_base_m": env.rtde_tcp_base - nominal,
            "tracker_error_base_m": tracker_err,
            "tracker_valid": np.array([1.0 if env.scenario.tracker else 0.0]),
            "path_depth_m": np.array([env.path.s_m]),
            "phase": phase,
            "correction_base_m": env.correction_base_m,
            "feed_scale": np.array([env.feed_scale]),
        }
    )


def reference_info(env: Any) -> dict[str, Any]:
    """The info dict as the original ``_info`` built it."""
    cell = env.cell
    smp = cell.sample
    force = np.asarray(smp.force)
    info: dict[str, Any] = {
        "t_s": env.t_s,
        "phase": int(env.path.phase),
        "stage": smp.stage,
        "depth_cmd_m": env.path.s_m,
        "tip_pos_task_m": np.array(smp.tip),
        "deviation_m": math.hypot(smp.tip[0], smp.tip[1]),
        "tip_deflection_robot_m": cell.C_robot @ force,
        "tip_deflection_tool_m": cell.C_tool @ force,
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


def reference_step(env: Any, action: np.ndarray) -> tuple[dict[str, np.ndarray], float, bool, bool, dict[str, Any]]:
    """One agent step of ``env`` (the unwrapped env) computed the original way."""
    a = np.asarray(action, dtype=float)
    assert a.shape == (ACTION_DIM,) and np.all(np.isfinite(a))
    assert env.path.phase != Phase.DONE and env.failure is None
    a = np.clip(a, -1.0, 1.0)
    corr, scale = scale_action(a)
    fx = env.effects
    delay_s = env.scenario.latency_s if fx is None else fx.command_delay_s(env, env.scenario.latency_s)
    env.pending.append((env.t_s + delay_s, corr, scale))
    sc = env.scenario
    cell = env.cell
    rt = cell.R_base_task.T
    rtde_time = latest_sample_time_s(env.t_s + CONTROL_DT_S, RTDE_RATE_HZ)
    wrenches = np.empty((SUBSTEPS_PER_STEP, 6))
    samples = []
    rows = env.recorder.extend(SUBSTEPS_PER_STEP)  # the record's layout: columns of drillgym.envs.step_kernel
    if fx is None:
        offset, hook = None, None
    else:
        fx.begin_step(env)
        offset, hook = fx.target_offset_task_m(cell.geometry_offset_task_m), fx.target_hook
    _begin_step(env)
    cx, cy, cz = _servo_xyz(env, rt, offset)
    for k in range(SUBSTEPS_PER_STEP):
        t_next = env.t_s + PHYSICS_DT_S
        while env.pending and env.pending[0][0] <= t_next + 1e-12:
            _, env.correction_base_m, scale = env.pending.popleft()
            if scale != env.feed_scale:
                env.feed_scale = scale
                _begin_step(env)
            cx, cy, cz = _servo_xyz(env, rt, offset)
        phase = env.path.phase
        s = env.path.advance(PHYSICS_DT_S, env.feed_scale)
        if env.t_s <= rtde_time < t_next:
            env.rtde_tcp_base = _tcp_rtde_base_m(cell)
        target = (cx, cy, cz + s) if hook is None else hook(t_next, (cx, cy, cz + s))
        smp = cell.sample = _update(cell.solver, target, env.cell.servo_gain)
        samples.append(smp)
        env.t_s = t_next
        fx_, fy_, fz_ = smp.force
        arm = cell.sensor_arm_m
        wrenches[k] = (fx_, fy_, fz_, -arm * fy_, arm * fx_, smp.torque_axis)
        rows[k, OUT_T_S] = env.t_s
        rows[k, OUT_PHASE] = phase.value
        rows[k, OUT_STAGE] = smp.stage
        rows[k, OUT_DEPTH_CMD] = s
        rows[k, OUT_DEVIATION] = math.hypot(smp.tip[0], smp.tip[1])
        rows[k, OUT_TIP : OUT_TIP + 3] = smp.tip
        rows[k, OUT_CUTTING] = 1.0 if smp.cutting else 0.0
    if fx is not None:
        wrenches = fx.sensor_wrenches(env, wrenches, rows[:, OUT_T_S].copy())
    readings = _sample_block(env.ft, wrenches)
    rows[:, OUT_FORCE : OUT_TORQUE + 3] = readings
    if env.failure is None and float(np.max(np.linalg.norm(readings[:, :3], axis=1))) > sc.force_limit_n:
        env.failure = "force_limit"
    if rtde_time >= env.t_s - 1e-12:
        env.rtde_tcp_base = _tcp_rtde_base_m(cell)
    env.ft_last = readings[-1]
    env.ft_mean = readings.mean(axis=0)
    _end_step(cell)
    _sample_tracker(env)
    rows[:, OUT_TRACKER_DEVIATION] = env.tracker_lateral_m
    dev_mean = sum(math.hypot(x.tip[0], x.tip[1]) for x in samples) / SUBSTEPS_PER_STEP
    lat_mean = sum(math.hypot(x.force[0], x.force[1]) for x in samples) / SUBSTEPS_PER_STEP
    terms = {
        "deviation": -env.reward.deviation * dev_mean * 1e3,
        "force": -env.reward.force * lat_mean,
        "smooth": -env.reward.smooth * float(np.sum((a - env.prev_action) ** 2)),
        "peak_force": -env.reward.peak_force * max(lat_mean - env.peak_lateral_n, 0.0),
    }
    env.peak_lateral_n = max(env.peak_lateral_n, lat_mean)
    env.step_terms = terms
    env.prev_action = a
    terminated = env.path.phase == Phase.DONE or env.failure is not None
    env.steps += 1
    at_limit = env.t_s >= env.max_time_s or env.steps >= MAX_EPISODE_STEPS
    truncated = env.truncated = (not terminated) and at_limit
    if terminated or truncated:
        env.metrics = env.episode_metrics()
    return reference_observation(env), float(sum(terms.values())), terminated, truncated, reference_info(env)
