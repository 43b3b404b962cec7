"""One agent step of the simulated cell, compiled (numba): the env's physics on plain arrays.

:meth:`UR5BoneDrillEnv.advance <drillgym.envs.drill_env.UR5BoneDrillEnv.advance>` without unmodelled
effects or with the compiled ones (:attr:`Effect.compiled <drillgym.envs.effects.base.Effect.compiled>`: a
depth profile of the forces, the tool's length, a kinematic offset, skid friction, thermal softening, joint
friction, joint backlash, spindle sag, a registration error), in one call: the command queue
(latency), the nominal path, the tip balance of the five F/T samples (:func:`~drillgym.envs.drilling.contact_kernel.run_samples`), the F/T readings, the RTDE TCP,
the arm's inverse kinematics and compliance, and the tracker. Both envs call :func:`advance_batch`: the
single env for its one episode, the batched env (:mod:`drillgym.envs.batched`) for N at once. The physics is
documented where the Python objects hold it (:mod:`drillgym.envs.cell`, :mod:`drillgym.envs.drilling.contact`);
this module only lays it out on arrays.

The randomness is drawn outside, by the episode's own generator, in the order the env draws it (the F/T
noise, then the tracker's when its sample is new), so a seeded episode reads the same noise either way.

N episodes' arrays travel together as :class:`KernelArrays`, each with the episode as first axis: ``state``
and ``params``, the named state and constant parameters (:mod:`drillgym.envs.episode_state`); ``pend`` the
command queue (rows ``t_apply_s, correction_base_m (3), feed_scale``); ``tab`` the force table
(:data:`TABLE_ROWS`); ``rows`` the cutting forces for the chip in effect; ``chains`` the TCP's and the
tracker marker's packed chains; the hole (``centre``, ``filled``, ``bins``); and the servo target's delay line
(``delay``, :data:`DELAY_ROWS`). ``out`` takes a step's five sample rows for the recorder (:data:`OUT_COLUMNS`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numba
import numpy as np

from drillgym.envs.constants import (
    APPROACH_SPEED_M_S,
    APPROACH_START_M,
    CONTROL_DT_S,
    FEED_START_M,
    FT_RESOLUTION,
    MAX_EPISODE_STEPS,
    PHYSICS_DT_S,
    RETRACT_SPEED_M_S,
    RTDE_RATE_HZ,
    SUBSTEPS_PER_STEP,
    TRACKER_RATE_HZ,
)
from drillgym.envs.drilling.contact_kernel import run_samples
from drillgym.envs.effects.backlash import move_links_kernel
from drillgym.envs.effects.bone import soften
from drillgym.envs.effects.joints import friction_lag
from drillgym.envs.effects.sensor import drifted
from drillgym.envs.effects.spindle import sag
from drillgym.envs.effects.timing import delayed
from drillgym.envs.interp_kernel import interp_one
from drillgym.envs.robot.ur5_kernel import compliance_into, deflected_into, ik_step_into, jacobian_into, pose
from drillgym.envs.sample_record import (
    OUT_CUTTING,
    OUT_DEPTH_CMD,
    OUT_DEVIATION,
    OUT_FORCE,
    OUT_PHASE,
    OUT_STAGE,
    OUT_T_S,
    OUT_TIP,
    OUT_TRACKER_DEVIATION,
)

PENDING_ROWS = 16
"""Capacity of the command queue (a latency of up to 0.5 s queues at most 11 commands)."""

DELAY_ROWS = 1024
"""Capacity of the delay line ``delay`` (rows ``t_s, target (3, m, task frame)``, one per sample); when full,
its newest half is kept, 0.512 s of samples, more than the longest extra latency (0.3 s) reads back."""

TABLE_ROWS = 11
"""``tab`` rows (one column per grid depth): depth (m), edge forces (4), per-chip forces (4), engaged fraction,
the depth profile's factor on the forces (1 without one; :meth:`TipContactSolver.set_depth_profile`)."""


class KernelArrays(NamedTuple):
    """N episodes' arrays, each with the episode as first axis, in the kernels' argument order."""

    state: np.ndarray
    params: np.ndarray
    pend: np.ndarray
    tab: np.ndarray
    rows: np.ndarray
    chains: np.ndarray
    centre: np.ndarray
    filled: np.ndarray
    bins: np.ndarray
    delay: np.ndarray


APPROACH, FEED, RETRACT, DONE = 0, 1, 2, 3

# In the functions below ``s`` is one episode's state record (:data:`~drillgym.envs.episode_state.STATE`) and
# ``p`` its parameters (:data:`~drillgym.envs.episode_state.PARAMS`); both are written in place.


@numba.njit(cache=True)
def _speed_m_s(phase: int, feed_m_s: float, feed_scale: float) -> float:  # pragma: no cover (compiled)
    """:meth:`DrillPath.speed_m_s <drillgym.envs.task.DrillPath.speed_m_s>`."""
    if phase == APPROACH:
        return APPROACH_SPEED_M_S
    if phase == FEED:
        return feed_m_s * feed_scale
    if phase == RETRACT:
        return -RETRACT_SPEED_M_S
    return 0.0


@numba.njit(cache=True)
def _path_advance(s, depth_m: float, feed_m_s: float) -> float:  # pragma: no cover (compiled)
    """:meth:`DrillPath.advance <drillgym.envs.task.DrillPath.advance>` by one physics update; the new depth (m)."""
    phase = s.phase
    d = s.path_m + _speed_m_s(phase, feed_m_s, s.feed_scale) * PHYSICS_DT_S
    if phase == APPROACH and d >= -FEED_START_M:
        s.phase = FEED
    elif phase == FEED and d >= depth_m:
        d = depth_m
        s.phase = RETRACT
    elif phase == RETRACT and d <= -APPROACH_START_M:
        d = -APPROACH_START_M
        s.phase = DONE
    s.path_m = d
    return d


@numba.njit(cache=True)
def _advance_m(s, pend: np.ndarray, p) -> float:  # pragma: no cover (compiled)
    """Axial advance of the commanded tip per physics update over the step (m): ``UR5BoneDrillEnv._advance_m``."""
    t_s = s.t_s
    last = -1
    for k in range(s.pending):
        if pend[k, 0] <= t_s + CONTROL_DT_S + 1e-12:
            last = k
    dz = 0.0
    if last >= 0:
        r, c = p.R_base_task, s.correction_base_m
        dz = r[0, 2] * (pend[last, 1] - c[0]) + r[1, 2] * (pend[last, 2] - c[1]) + r[2, 2] * (pend[last, 3] - c[2])
    per_step = _speed_m_s(s.phase, p.feed_m_s, s.feed_scale) * CONTROL_DT_S + dz
    return max(per_step / SUBSTEPS_PER_STEP, 0.0)


@numba.njit(cache=True)
def _prepare(s, pend: np.ndarray, p, tab: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, float]:  # pragma: no cover
    """``cell.begin_step``: the force rows for the chip in effect and the guided lateral stiffness (N/m)."""
    n = p.n_grid
    chip = p.feed_m_s * s.feed_scale / (p.n_lips * p.rev_per_s * s.spindle_share) * p.sin_kappa
    scale = s.force_scale_now
    if chip != s.key_chip_m or scale != s.key_scale:
        s.key_chip_m, s.key_scale = chip, scale
        for i in range(n):
            for c in range(4):
                rows[i, c] = scale * (tab[1 + c, i] + chip * tab[5 + c, i]) * tab[10, i]
    d = s.tip_balance[7]
    share = interp_one(tab[0], tab[9], n, d, tab[9, 0], tab[9, n - 1])  # np.interp's numbers
    g = share**p.guidance_exponent
    floor = p.wall_floor
    if floor < 1.0:
        wall = min(max((d - p.stage_bounds_m[3]) / p.wall_length_m, 0.0), 1.0)
        g = g * (floor + (1.0 - floor) * wall)
    if p.entry_guidance != 0.0 and share < 1.0:
        g = g + p.entry_guidance * (1.0 - share)
    k_cut = p.k_lat_n / max(_advance_m(s, pend, p), 1e-7)
    return rows[:n], k_cut * g


@numba.njit(cache=True)
def _servo_xyz(s, p) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """The correction in effect in the task frame (m): ``R_base_taskᵀ · correction_base``."""
    r = p.R_base_task
    c0, c1, c2 = s.correction_base_m[0], s.correction_base_m[1], s.correction_base_m[2]
    x = r[0, 0] * c0 + r[1, 0] * c1 + r[2, 0] * c2
    y = r[0, 1] * c0 + r[1, 1] * c1 + r[2, 1] * c2
    z = r[0, 2] * c0 + r[1, 2] * c1 + r[2, 2] * c2
    if p.target_offset_on:
        o = s.target_offset_task_m
        return x + o[0], y + o[1], z + o[2]
    return x, y, z


@numba.njit(cache=True)
def _solve(
    s,
    p,
    tab: np.ndarray,
    rows: np.ndarray,
    k_guided: float,
    c_total: np.ndarray,
    targets: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """The tip balance over ``targets``: :meth:`TipContactSolver.run`; its rows into ``out``."""
    n = p.n_grid
    b = p.stage_bounds_m
    touching, j = run_samples(
        targets,
        p.servo_gain,
        s.tip_balance,
        s.touching,
        s.bracket,
        p.tan_beta,
        (b[0], b[1], b[2], b[3]),
        tab[0, :n],
        rows,
        c_total,
        k_guided,
        centre,
        filled,
        bins,
        p.bin_m,
        out,
    )
    s.touching = touching
    s.bracket = j


@numba.njit(cache=True)
def _rtde_tcp(s, p, row: np.ndarray) -> None:  # pragma: no cover (compiled)
    """The RTDE TCP (base frame, m) where the encoders put the servo-held tip of sample ``row``."""
    r = p.R_base_task
    x, y, z = row[3], row[4], row[5]
    if p.geometry_on:
        g = s.geometry_offset_task_m
        x, y, z = x - g[0], y - g[1], z - g[2]
    for i in range(3):
        s.rtde_tcp_base_m[i] = p.entry_base_m[i] + (r[i, 0] * x + r[i, 1] * y + r[i, 2] * z)


@numba.njit(cache=True)
def _c_total(s, p) -> np.ndarray:  # pragma: no cover (compiled)
    """Arm + drill compliance (3x3, m/N, task axes)."""
    c = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            c[i, k] = s.c_robot_m_n[i, k] + p.C_tool[i, k]
    return c


@numba.njit(cache=True)
def _pose_cached(s) -> bool:  # pragma: no cover (compiled)
    """Whether ``s.tcp_pose_base`` is the TCP's pose at the motor angles (the same bits: signs of zeros too)."""
    for i in range(s.q_motor_rad.shape[0]):
        a, b = s.q_motor_rad[i], s.tcp_pose_q_rad[i]
        if not (a == b and math.copysign(1.0, a) == math.copysign(1.0, b)):
            return False
    return True


@numba.njit(cache=True)
def _cached_pose(s):  # pragma: no cover (compiled)
    """``s.tcp_pose_base`` as :func:`~drillgym.envs.robot.ur5_kernel.pose` gives a pose (tuples)."""
    c = s.tcp_pose_base
    return (c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8]), (c[9], c[10], c[11])


@numba.njit(cache=True)
def advance(  # noqa: C901 (one step, in the env's order)
    s,
    p,
    pend: np.ndarray,
    tab: np.ndarray,
    rows: np.ndarray,
    chains: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
    delay: np.ndarray,
    command: np.ndarray,
    noise: np.ndarray,
    out: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """One agent step of one episode (its state record ``s``, parameters ``p`` and buffers) for ``command``.

    ``command``: the correction (3, m, base frame) and the feed scale; ``noise``: the episode's buffer of standard
    normals, read from ``s.noise_at`` on in the order the episode's generator drew them: the F/T's (5x6, row-major)
    if it is noisy, then the tracker's (3) if it is noisy and its sample is new; ``s.noise_at`` moves past them. Sets ``s.terminated``,
    ``s.truncated`` and, on a singular Jacobian, ``s.singular`` (the state is then not advanced further).
    """
    # queue the command; it applies after the latency
    npend = s.pending
    pend[npend, 0] = s.t_s + p.latency_s
    pend[npend, 1:4] = command[:3]
    pend[npend, 4] = command[3]
    s.pending = npend + 1
    # the compiled effects' step hooks, beside their Python hooks in envs/effects, in the Python step's order
    if p.softening > 0.0:
        soften(s, p, _speed_m_s(s.phase, p.feed_m_s, s.feed_scale))
    if p.backlash_half_rad > 0.0:
        move_links_kernel(s, p, chains)
    if p.friction_on:
        friction_lag(s, p, pend, _speed_m_s(s.phase, p.feed_m_s, s.feed_scale))
    if p.spindle_sag_per_nm > 0.0:
        sag(s, p)
    rtde_time = math.floor((s.t_s + CONTROL_DT_S) * RTDE_RATE_HZ + 1e-9) / RTDE_RATE_HZ
    c_total = _c_total(s, p)
    nb = p.n_bins
    hole_c, hole_f = centre[:nb], filled[:nb]
    frows, k_guided = _prepare(s, pend, p, tab, rows)
    cx, cy, cz = _servo_xyz(s, p)
    n = SUBSTEPS_PER_STEP
    targets = np.empty((n, 3))
    smp = np.empty((n, 13))
    done = 0
    rtde_k = -1
    t_s = s.t_s
    for k in range(n):
        t_next = t_s + PHYSICS_DT_S
        while s.pending > 0 and pend[0, 0] <= t_next + 1e-12:
            s.correction_base_m[:] = pend[0, 1:4]
            scale = pend[0, 4]
            for j in range(s.pending - 1):
                pend[j] = pend[j + 1]
            s.pending -= 1
            if scale != s.feed_scale:
                if k > done:
                    _solve(s, p, tab, frows, k_guided, c_total, targets[done:k], hole_c, hole_f, bins, smp[done:k])
                    done = k
                s.feed_scale = scale
                s.t_s = t_s
                frows, k_guided = _prepare(s, pend, p, tab, rows)
            cx, cy, cz = _servo_xyz(s, p)
        phase = s.phase
        d = _path_advance(s, p.depth_m, p.feed_m_s)
        if t_s <= rtde_time < t_next:
            rtde_k = k
        if p.extra_latency_s > 0.0:
            targets[k, 0], targets[k, 1], targets[k, 2] = delayed(s, delay, t_next, cx, cy, cz + d, p.extra_latency_s)
        else:
            targets[k, 0], targets[k, 1], targets[k, 2] = cx, cy, cz + d
        out[k, OUT_T_S] = t_next
        out[k, OUT_PHASE] = phase
        out[k, OUT_DEPTH_CMD] = d
        t_s = t_next
    if n > done:
        _solve(s, p, tab, frows, k_guided, c_total, targets[done:n], hole_c, hole_f, bins, smp[done:n])
    s.t_s = t_s
    s.sample[:] = smp[n - 1]
    if rtde_k >= 0:  # the RTDE sample saw the servo-held tip before sample rtde_k
        _rtde_tcp(s, p, smp[rtde_k - 1] if rtde_k > 0 else smp[n - 1])
    # F/T readings: the true wrench at the sensor, the force drift (ft_drift), noise, quantisation
    arm = p.sensor_arm_m
    ft_std = p.ft_std
    rate = p.ft_drift_rate_n_s
    drift = rate[0] != 0.0 or rate[1] != 0.0 or rate[2] != 0.0  # off: the forces as they are (no -0.0 + 0.0)
    at = s.noise_at
    dev_sum = 0.0
    lat_sum = 0.0
    mean = np.zeros(6)
    over = False
    for k in range(n):
        f0, f1, f2 = smp[k, 6], smp[k, 7], smp[k, 8]
        r0, r1, r2 = drifted(rate, out[k, OUT_T_S], f0, f1, f2) if drift else (f0, f1, f2)
        w = (r0, r1, r2, -arm * f1, arm * f0, smp[k, 9])  # the torques from the true forces
        for c in range(6):
            v = w[c] + ft_std[c] * noise[at + 6 * k + c] if ft_std[0] > 0.0 else w[c]
            v = np.rint(v / FT_RESOLUTION[c]) * FT_RESOLUTION[c]
            out[k, OUT_FORCE + c] = v  # the force, then the torque (OUT_TORQUE)
            mean[c] = v if k == 0 else mean[c] + v
        f = OUT_FORCE
        if math.sqrt(out[k, f] ** 2 + out[k, f + 1] ** 2 + out[k, f + 2] ** 2) > p.force_limit_n:
            over = True
        dev = math.hypot(smp[k, 0], smp[k, 1])
        out[k, OUT_STAGE] = smp[k, 11]
        out[k, OUT_DEVIATION] = dev
        out[k, OUT_TIP : OUT_TIP + 3] = smp[k, 0:3]
        out[k, OUT_CUTTING] = smp[k, 12]
        dev_sum += dev
        lat_sum += math.hypot(f0, f1)
    if ft_std[0] > 0.0:
        at += 6 * n
    s.noise_at = at
    if over:
        s.failure = True
    if rtde_time >= s.t_s - 1e-12:
        _rtde_tcp(s, p, smp[n - 1])
    for c in range(6):
        s.ft_last[c] = out[n - 1, OUT_FORCE + c]
        s.ft_mean[c] = mean[c] / n
    # the arm follows the servo target: one Newton step of IK, then J and the compliance at the new angles
    r_task = p.R_base_task
    stiffness = p.stiffness_nm_rad
    last = smp[n - 1]
    if p.geometry_on:
        g = s.geometry_offset_task_m
        rigid = (last[3] - g[0], last[4] - g[1], last[5] - g[2])
    else:
        rigid = (last[3], last[4], last[5])
    joints = s.q_motor_rad.shape[0]
    solve_m, vec, rows_j = np.empty((joints, joints)), np.empty((3, joints)), np.empty((2, joints, 3))  # scratch
    q = vec[0]
    pose_q = _cached_pose(s) if _pose_cached(s) else pose(s.q_motor_rad, chains[0])
    ik_step_into(s.q_motor_rad, pose_q, s.jacobian, rigid, p.entry_base_m, r_task, solve_m, vec[1], q)
    for i in range(joints):
        if not math.isfinite(q[i]):
            s.singular = True
            return
    s.q_motor_rad[:] = q
    r_new, p_new = jacobian_into(q, chains[0], s.jacobian, rows_j[0], rows_j[1])
    for i in range(9):  # the pose at the new angles, for the next step's IK
        s.tcp_pose_base[i] = r_new[i]
    for i in range(3):
        s.tcp_pose_base[9 + i] = p_new[i]
    s.tcp_pose_q_rad[:] = q
    compliance_into(s.jacobian, stiffness, r_task, s.c_robot_m_n)
    # the tracker: a new sample of the true (deflected) marker at its rate, against the nominal path
    stamp = math.floor(s.t_s * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ
    s.tracker_new = False
    if stamp != s.tracker_stamp_s:
        s.tracker_new = True
        s.tracker_stamp_s = stamp
        q_true = vec[2]
        deflected_into(q, s.jacobian, (last[6], last[7], last[8]), last[9], r_task, stiffness, q_true)
        marker = pose(q_true, chains[1])[1]
        if p.marker_on:
            o = s.marker_offset_base_m
            marker = (marker[0] + o[0], marker[1] + o[1], marker[2] + o[2])
        noise_m = p.tracker_noise_m
        for i in range(3):
            s.tracker_reading_base_m[i] = marker[i] + noise_m * noise[at + i] if noise_m > 0.0 else marker[i]
        if noise_m > 0.0:
            s.noise_at = at + 3
    along = s.path_m - p.s_start_m
    err = s.tracker_error_base_m
    for i in range(3):
        planned = p.marker_start_base_m[i] + r_task[i, 2] * along  # + R_base_task · (0, 0, along)
        err[i] = s.tracker_reading_base_m[i] - planned
    lat0 = r_task[0, 0] * err[0] + r_task[1, 0] * err[1] + r_task[2, 0] * err[2]
    lat1 = r_task[0, 1] * err[0] + r_task[1, 1] * err[1] + r_task[2, 1] * err[2]
    s.tracker_lateral_m = math.hypot(lat0, lat1)
    for k in range(n):
        out[k, OUT_TRACKER_DEVIATION] = s.tracker_lateral_m
    s.step_deviation_m = dev_sum / n
    s.step_lateral_n = lat_sum / n
    terminated = s.phase == DONE or s.failure
    s.steps += 1
    at_limit = s.t_s >= p.max_time_s or s.steps >= MAX_EPISODE_STEPS
    s.terminated = terminated
    s.truncated = (not terminated) and at_limit


@numba.njit(cache=True)
def advance_batch(
    state: np.ndarray,
    params: np.ndarray,
    pend: np.ndarray,
    tab: np.ndarray,
    rows: np.ndarray,
    chains: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
    delay: np.ndarray,
    command: np.ndarray,
    noise: np.ndarray,
    record: np.ndarray,
    recorded: np.ndarray,
    active: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """:func:`advance` for every active episode of N episodes' arrays (:class:`KernelArrays`, in order).

    ``command`` (N, 4) holds each episode's command and ``noise`` (N, M) its buffer of standard normals, read from
    its ``noise_at`` on (:func:`advance`); ``active`` (N, bool) which episodes step (the others are left as they are).
    The step's rows go to ``record[i]`` from row ``recorded[i]`` on, which advances by five (the caller sizes
    ``record`` for the longest episode). The single env is N = 1.
    """
    n = SUBSTEPS_PER_STEP
    for i in range(state.shape[0]):
        if not active[i]:
            continue
        k = recorded[i]
        advance(
            state[i], params[i], pend[i], tab[i], rows[i], chains[i], centre[i], filled[i], bins[i], delay[i],
            command[i], noise[i], record[i, k : k + n],
        )  # fmt: skip
        recorded[i] = k + n


@numba.njit(cache=True, parallel=True)
def advance_batch_threaded(
    state: np.ndarray,
    params: np.ndarray,
    pend: np.ndarray,
    tab: np.ndarray,
    rows: np.ndarray,
    chains: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
    delay: np.ndarray,
    command: np.ndarray,
    noise: np.ndarray,
    record: np.ndarray,
    recorded: np.ndarray,
    active: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """:func:`advance_batch` with the episodes spread over numba's threads (``numba.set_num_threads``).

    The same numbers: each episode's step is the same compiled :func:`advance` on its own rows of every array,
    and no episode reads another's.
    """
    n = SUBSTEPS_PER_STEP
    for i in numba.prange(state.shape[0]):
        if active[i]:
            k = recorded[i]
            advance(
                state[i], params[i], pend[i], tab[i], rows[i], chains[i], centre[i], filled[i], bins[i], delay[i],
                command[i], noise[i], record[i, k : k + n],
            )  # fmt: skip
            recorded[i] = k + n


@numba.njit(cache=True)
def advance_open_loop(
    state: np.ndarray,
    params: np.ndarray,
    pend: np.ndarray,
    tab: np.ndarray,
    rows: np.ndarray,
    chains: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
    delay: np.ndarray,
    commands: np.ndarray,
    out: np.ndarray,
    q_motor: np.ndarray,
    tracker: np.ndarray,
) -> int:  # pragma: no cover (compiled)
    """:func:`advance` of episode 0 through ``commands`` (T, 4) until the episode ends, without noise; the steps taken.

    Sample rows go to ``out`` (5 T, :data:`OUT_COLUMNS`); after each step the motor angles (rad) to
    ``q_motor[k]`` (T, 6) and the tracker reading (m, base frame) to ``tracker[k]`` (T, 3). Stops at a
    singular Jacobian with ``singular`` set (that step not counted).
    """
    n = SUBSTEPS_PER_STEP
    noise = np.zeros(6 * n + 3)
    s, p = state[0], params[0]
    for k in range(commands.shape[0]):
        advance(
            s, p, pend[0], tab[0], rows[0], chains[0], centre[0], filled[0], bins[0], delay[0], commands[k], noise,
            out[n * k : n * k + n],
        )  # fmt: skip
        if s.singular:
            return k
        q_motor[k] = s.q_motor_rad
        tracker[k] = s.tracker_reading_base_m
        if s.terminated or s.truncated:
            return k + 1
    return commands.shape[0]
