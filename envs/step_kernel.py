"""One agent step of the simulated cell, compiled (numba): the env's physics on plain arrays.

:meth:`UR5BoneDrillEnv.advance <drillgym.envs.drill_env.UR5BoneDrillEnv.advance>` without unmodelled
effects or with the compiled ones (:attr:`Effect.compiled <drillgym.envs.effects.base.Effect.compiled>`: a
depth profile of the forces, the tool's length, a kinematic offset, skid friction, thermal softening, joint
friction, joint backlash, spindle sag, a registration error), in one call: the command queue
(latency), the nominal path, the tip balance of the five F/T samples (:func:`~drillgym.envs.drilling.contact_kernel.run_samples`), the F/T readings, the RTDE TCP,
the arm's inverse kinematics and compliance, and the tracker. The single env calls :func:`advance`
for its own state; the batched env (:mod:`drillgym.envs.batched`) calls :func:`advance_batch` for N
episodes at once. The physics is documented where the Python objects hold it (:mod:`drillgym.envs.cell`,
:mod:`drillgym.envs.drilling.contact`); this module only lays it out on arrays.

The randomness is drawn outside, by the episode's own generator, in the order the env draws it (the F/T
noise, then the tracker's when its sample is new), so a seeded episode reads the same noise either way.

An episode's arrays travel together as :class:`KernelArrays` (index constants below): ``fs`` the float
state, ``ist`` the integer state, ``pend`` the command queue (rows ``t_apply_s, correction_base_m (3),
feed_scale``), ``par`` the episode's constant parameters, ``tab`` the force table (:data:`TABLE_ROWS`),
``rows`` the cutting forces for the chip in effect, ``chains`` the TCP's and the tracker marker's packed
chains, the hole (``centre``, ``filled``, ``bins``) and the servo target's delay line (``delay``,
:data:`DELAY_ROWS`). ``out`` takes the step's five sample rows for the
recorder (:data:`OUT_COLUMNS`).
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
from drillgym.envs.effects.bone import MIN_HARDNESS
from drillgym.envs.effects.joints import SIGN_SMOOTHING_RAD_S
from drillgym.envs.effects.spindle import MIN_SPEED_SHARE
from drillgym.envs.robot.ur5_kernel import frame_pose, ik_step, jacobian_and_compliance, joint_deflection

# ---------------------------------------------------------------- float state ``fs``
T_S = 0
"""Simulated time (s)."""
PATH_S = 1
"""Nominal depth along the planned axis (m)."""
FEED_SCALE = 2
"""Feed override in effect (-)."""
CORRECTION = 3
"""Tip correction in effect (3, m, base frame)."""
SOLVER = 6
"""The tip balance's state (8, :data:`~drillgym.envs.drilling.contact_kernel.STATE_SIZE`)."""
KEY_CHIP = 14
"""Chip thickness (m) the cached force rows ``rows`` were made for (NaN: none yet)."""
KEY_SCALE = 15
"""Specimen hardness factor the cached force rows were made for."""
RTDE_TCP = 16
"""The RTDE TCP position (3, m, base frame)."""
FT_LAST = 19
"""Latest F/T reading (6, N and N·m, sensor frame)."""
FT_MEAN = 25
"""Mean of the step's F/T readings (6)."""
TRACKER_STAMP = 31
"""Time stamp of the latest tracker sample (s; -1 before the first)."""
TRACKER_READING = 32
"""Latest tracker reading (3, m, base frame)."""
TRACKER_ERROR = 35
"""Tracker reading minus where a rigid arm on the nominal path puts the marker (3, m, base frame)."""
TRACKER_LATERAL = 38
"""Lateral part of the tracker error (m, task xy)."""
STEP_DEVIATION = 39
"""Mean true tip deviation over the step's samples (m)."""
STEP_LATERAL = 40
"""Mean true lateral force over the step's samples (N)."""
Q_MOTOR = 41
"""Motor-side joint angles (6, rad)."""
JACOBIAN = 47
"""TCP Jacobian at ``Q_MOTOR`` (36, row-major 6x6, base axes)."""
C_ROBOT = 83
"""Arm compliance at the TCP (9, row-major 3x3, m/N, task axes)."""
SAMPLE = 92
"""The latest sample's row (13, :data:`~drillgym.envs.drilling.contact_kernel.ROW_SIZE`)."""
TARGET_OFFSET = 105
"""This step's shift of the servo target (3, m, task frame): the tool's geometry offset (``GEOMETRY_OFFSET``, set at
load and moved by joint backlash) plus, with joint friction, its servo lag (used where ``par[TARGET_OFFSET_ON]``)."""
WORK_J = 108
"""Cutting work done so far (J; thermal softening)."""
FORCE_SCALE_NOW = 109
"""The force scale in effect: the specimen's (``par[FORCE_SCALE]``), after thermal softening if on."""
SPINDLE_SHARE = 110
"""The spindle's speed as a share of the scenario's (1 without spindle sag)."""
GEOMETRY_OFFSET = 111
"""Where the physical tool sits away from the controller's model (3, m, task frame;
:attr:`SimCell.geometry_offset_task_m <drillgym.envs.cell.SimCell.geometry_offset_task_m>`; used where
``par[GEOMETRY_ON]``): constant but for joint backlash, whose links move it."""
MARKER_OFFSET = 114
"""The same for the tracker marker (3, m, base frame; used where ``par[MARKER_ON]``)."""
LINK_Q = 117
"""Joint backlash: the link angles of the first three joints (3, rad)."""
LINK_TIP = 120
"""Joint backlash: its share of the geometry offset (3, m, task frame)."""
LINK_MARKER = 123
"""Joint backlash: its share of the marker offset (3, m, base frame)."""
FLOAT_STATE_SIZE = 126

# ---------------------------------------------------------------- integer state ``ist``
PHASE = 0
"""Path phase (:class:`~drillgym.envs.task.Phase`)."""
TOUCHING = 1
"""Whether the tip touched bone at the latest sample (0/1)."""
BRACKET = 2
"""The depth grid's bracket of the latest root (warm start)."""
FAILURE = 3
"""1 once the measured force exceeded the limit."""
STEPS = 4
"""Agent steps taken."""
PENDING = 5
"""Commands queued in ``pend``."""
TERMINATED = 6
TRUNCATED = 7
SINGULAR = 8
"""1 if the inverse kinematics met a singular Jacobian (the caller raises)."""
TRACKER_NEW = 9
"""1 if this step's tracker sample is new (its noise was drawn)."""
DELAY_COUNT = 10
"""Samples held in the delay line ``delay`` (extra latency)."""
INT_STATE_SIZE = 11

PENDING_ROWS = 16
"""Capacity of the command queue (a latency of up to 0.5 s queues at most 11 commands)."""

# ---------------------------------------------------------------- parameters ``par``
LATENCY_S = 0
SERVO_GAIN = 1
TAN_BETA = 2
K_LAT = 3
GUIDANCE_EXPONENT = 4
WALL_FLOOR = 5
WALL_LENGTH = 6
FORCE_SCALE = 7
TRACKER_NOISE = 8
FORCE_LIMIT = 9
SENSOR_ARM = 10
DEPTH = 11
FEED_M_S = 12
MAX_TIME_S = 13
N_LIPS = 14
REV_PER_S = 15
SIN_KAPPA = 16
R_BASE_TASK = 17
"""9, row-major."""
ENTRY_BASE = 26
C_TOOL = 29
"""9, row-major (m/N, task axes)."""
STIFFNESS = 38
"""6 (N·m/rad)."""
MARKER_START = 44
"""The tracker marker's model position at the start (3, m, base frame)."""
S_START = 47
BOUNDS = 48
"""The stage bounds (4, m)."""
FT_STD = 52
"""F/T noise std per axis (6)."""
N_GRID = 58
"""Rows of the force table in use."""
N_BINS = 59
"""Bins of the hole in use."""
BIN_M = 60
BACKLASH_HALF = 61
"""Joint backlash: half the play of each of the first three joints (rad; 0: off;
:class:`~drillgym.envs.effects.backlash.JointBacklash`)."""
GEOMETRY_ON = 62
"""1 if the cell has a geometry offset."""
MARKER_ON = 63
"""1 if the cell has a marker offset."""
TARGET_OFFSET_ON = 64
"""1 if the servo target is shifted (a geometry offset or joint friction)."""
ENTRY_GUIDANCE = 65
"""Extra side guidance while the lips enter (share of full guidance at first touch; skid friction)."""
SOFTENING = 66
"""Thermal softening: asymptotic fractional loss of hardness (0: off)."""
SOFTENING_WORK_J = 67
"""Thermal softening: cutting work for 63 % of the loss (J)."""
OMEGA = 68
"""Spindle speed (rad/s)."""
FRICTION_COULOMB = 69
"""Joint friction: Coulomb position error per moving joint (rad; 0 with the viscous term: off)."""
FRICTION_VISCOUS = 70
"""Joint friction: viscous position error per joint speed (s)."""
FRICTION_ON = 71
"""1 if the joint friction is on."""
EXTRA_LATENCY = 72
"""Extra delay of the whole servo target (s; 0: off; :class:`~drillgym.envs.effects.timing.Latency`)."""
SPINDLE_SAG = 73
"""Spindle speed loss per N·m of cutting torque (1/(N·m); 0: off; :class:`~drillgym.envs.effects.spindle.SpindleSag`)."""
PARAM_SIZE = 74

DELAY_ROWS = 1024
"""Capacity of the delay line ``delay`` (rows ``t_s, target (3, m, task frame)``, one per sample); when full,
its newest half is kept, 0.512 s of samples, more than the longest extra latency (0.3 s) reads back."""

TABLE_ROWS = 11
"""``tab`` rows (one column per grid depth): depth (m), edge forces (4), per-chip forces (4), engaged fraction,
the depth profile's factor on the forces (1 without one; :meth:`TipContactSolver.set_depth_profile`)."""
OUT_T_S, OUT_PHASE, OUT_STAGE, OUT_DEPTH_CMD, OUT_DEVIATION = 0, 1, 2, 3, 4
"""``out`` columns: the sample's time (s), path phase, stage, commanded depth (m), true tip deviation (m)."""
OUT_TIP = 5
"""True tip position (3, m, task frame)."""
OUT_FORCE = 8
"""F/T force reading (3, N, sensor frame); the torque reading (3, N·m) follows."""
OUT_TORQUE = 11
OUT_TRACKER_DEVIATION = 14
"""Lateral tracker error (m)."""
OUT_CUTTING = 15
"""1 if the drill cut at the sample."""
OUT_COLUMNS = 16


class KernelArrays(NamedTuple):
    """One episode's arrays (or N episodes', each with the episode as first axis), in the kernels' argument order."""

    fs: np.ndarray
    ist: np.ndarray
    pend: np.ndarray
    par: np.ndarray
    tab: np.ndarray
    rows: np.ndarray
    chains: np.ndarray
    centre: np.ndarray
    filled: np.ndarray
    bins: np.ndarray
    delay: np.ndarray


APPROACH, FEED, RETRACT, DONE = 0, 1, 2, 3


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
def _path_advance(fs: np.ndarray, ist: np.ndarray, depth_m: float, feed_m_s: float) -> float:  # pragma: no cover
    """:meth:`DrillPath.advance <drillgym.envs.task.DrillPath.advance>` by one physics update; the new depth (m)."""
    phase = ist[PHASE]
    s = fs[PATH_S] + _speed_m_s(phase, feed_m_s, fs[FEED_SCALE]) * PHYSICS_DT_S
    if phase == APPROACH and s >= -FEED_START_M:
        ist[PHASE] = FEED
    elif phase == FEED and s >= depth_m:
        s = depth_m
        ist[PHASE] = RETRACT
    elif phase == RETRACT and s <= -APPROACH_START_M:
        s = -APPROACH_START_M
        ist[PHASE] = DONE
    fs[PATH_S] = s
    return s


@numba.njit(cache=True)
def _advance_m(fs: np.ndarray, ist: np.ndarray, pend: np.ndarray, par: np.ndarray) -> float:  # pragma: no cover
    """Axial advance of the commanded tip per physics update over the step (m): ``UR5BoneDrillEnv._advance_m``."""
    t_s = fs[T_S]
    last = -1
    for k in range(ist[PENDING]):
        if pend[k, 0] <= t_s + CONTROL_DT_S + 1e-12:
            last = k
    dz = 0.0
    if last >= 0:
        o = R_BASE_TASK
        dz = (
            par[o + 2] * (pend[last, 1] - fs[CORRECTION])
            + par[o + 5] * (pend[last, 2] - fs[CORRECTION + 1])
            + par[o + 8] * (pend[last, 3] - fs[CORRECTION + 2])
        )
    per_step = _speed_m_s(ist[PHASE], par[FEED_M_S], fs[FEED_SCALE]) * CONTROL_DT_S + dz
    return max(per_step / SUBSTEPS_PER_STEP, 0.0)


@numba.njit(cache=True)
def _prepare(
    fs: np.ndarray, ist: np.ndarray, pend: np.ndarray, par: np.ndarray, tab: np.ndarray, rows: np.ndarray
) -> tuple[np.ndarray, float]:  # pragma: no cover (compiled)
    """``cell.begin_step``: the force rows for the chip in effect and the guided lateral stiffness (N/m)."""
    n = int(par[N_GRID])
    chip = par[FEED_M_S] * fs[FEED_SCALE] / (par[N_LIPS] * par[REV_PER_S] * fs[SPINDLE_SHARE]) * par[SIN_KAPPA]
    scale = fs[FORCE_SCALE_NOW]
    if chip != fs[KEY_CHIP] or scale != fs[KEY_SCALE]:
        fs[KEY_CHIP], fs[KEY_SCALE] = chip, scale
        for i in range(n):
            for c in range(4):
                rows[i, c] = scale * (tab[1 + c, i] + chip * tab[5 + c, i]) * tab[10, i]
    d = fs[SOLVER + 7]
    share = np.interp(d, tab[0, :n], tab[9, :n])
    g = share ** par[GUIDANCE_EXPONENT]
    floor = par[WALL_FLOOR]
    if floor < 1.0:
        wall = min(max((d - par[BOUNDS + 3]) / par[WALL_LENGTH], 0.0), 1.0)
        g = g * (floor + (1.0 - floor) * wall)
    if par[ENTRY_GUIDANCE] != 0.0 and share < 1.0:
        g = g + par[ENTRY_GUIDANCE] * (1.0 - share)
    k_cut = par[K_LAT] / max(_advance_m(fs, ist, pend, par), 1e-7)
    return rows[:n], k_cut * g


@numba.njit(cache=True)
def _servo_xyz(fs: np.ndarray, par: np.ndarray) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """The correction in effect in the task frame (m): ``R_base_taskᵀ · correction_base``."""
    o = R_BASE_TASK
    c0, c1, c2 = fs[CORRECTION], fs[CORRECTION + 1], fs[CORRECTION + 2]
    x = par[o] * c0 + par[o + 3] * c1 + par[o + 6] * c2
    y = par[o + 1] * c0 + par[o + 4] * c1 + par[o + 7] * c2
    z = par[o + 2] * c0 + par[o + 5] * c1 + par[o + 8] * c2
    if par[TARGET_OFFSET_ON] == 1.0:
        return x + fs[TARGET_OFFSET], y + fs[TARGET_OFFSET + 1], z + fs[TARGET_OFFSET + 2]
    return x, y, z


@numba.njit(cache=True)
def _soften(fs: np.ndarray, ist: np.ndarray, par: np.ndarray) -> None:  # pragma: no cover (compiled)
    """Thermal softening's step start: the last step's cutting work added, the force scale it leaves.

    :class:`~drillgym.envs.effects.bone.ThermalSoftening`'s ``begin_step``.
    """
    o = SAMPLE
    speed = _speed_m_s(ist[PHASE], par[FEED_M_S], fs[FEED_SCALE])
    power_w = abs(fs[o + 9]) * par[OMEGA] + abs(fs[o + 8]) * max(speed, 0.0)
    fs[WORK_J] += power_w * CONTROL_DT_S
    factor = 1.0 - par[SOFTENING] * (1.0 - math.exp(-fs[WORK_J] / par[SOFTENING_WORK_J]))
    fs[FORCE_SCALE_NOW] = par[FORCE_SCALE] * max(factor, MIN_HARDNESS)


@numba.njit(cache=True)
def _backlash(fs: np.ndarray, par: np.ndarray, chains: np.ndarray) -> None:  # pragma: no cover (compiled)
    """The links of the first three joints kept within half the play of their motors; the tool and marker with them.

    :class:`~drillgym.envs.effects.backlash.JointBacklash`'s ``begin_step``: the links' offsets of the tool tip
    (task frame) and the marker (base frame) replace the effect's earlier share of the geometry offsets, and the
    servo-held point moves with the tip.
    """
    half = par[BACKLASH_HALF]
    q_m = fs[Q_MOTOR : Q_MOTOR + 6]  # read only here
    q_link = q_m.copy()
    for j in range(3):
        q_link[j] = min(max(fs[LINK_Q + j], q_m[j] - half), q_m[j] + half)
        fs[LINK_Q + j] = q_link[j]
    o = R_BASE_TASK
    r = par[o : o + 9].reshape((3, 3))
    tip = r.T @ (frame_pose(q_link, chains[0])[1] - frame_pose(q_m, chains[0])[1])
    marker = frame_pose(q_link, chains[1])[1] - frame_pose(q_m, chains[1])[1]
    for i in range(3):
        fs[GEOMETRY_OFFSET + i] = fs[GEOMETRY_OFFSET + i] - fs[LINK_TIP + i] + tip[i]
        fs[MARKER_OFFSET + i] = fs[MARKER_OFFSET + i] - fs[LINK_MARKER + i] + marker[i]
        fs[SOLVER + i] = fs[SOLVER + i] + (tip[i] - fs[LINK_TIP + i])
        fs[LINK_TIP + i], fs[LINK_MARKER + i] = tip[i], marker[i]
        fs[TARGET_OFFSET + i] = fs[GEOMETRY_OFFSET + i]


@numba.njit(cache=True)
def _friction_lag(fs: np.ndarray, ist: np.ndarray, pend: np.ndarray, par: np.ndarray) -> None:  # pragma: no cover
    """The step's servo-target shift (task frame, m): the geometry offset plus the joint friction's lag.

    The lag is :class:`~drillgym.envs.effects.joints.JointFriction`'s ``begin_step``, from the commanded tip
    velocity (the newest command is queued).
    """
    o = R_BASE_TASK
    r = par[o : o + 9].reshape((3, 3))
    v = np.zeros(3)
    v[2] = _speed_m_s(ist[PHASE], par[FEED_M_S], fs[FEED_SCALE])
    last = ist[PENDING] - 1
    d = np.empty(3)
    for i in range(3):
        d[i] = pend[last, 1 + i] - fs[CORRECTION + i]
    v += (r.T @ d) / CONTROL_DT_S
    twist = np.zeros(6)
    twist[:3] = r @ v
    jac = fs[JACOBIAN : JACOBIAN + 36].reshape((6, 6))
    qd = np.linalg.solve(jac, twist)
    dq = -(par[FRICTION_COULOMB] * np.tanh(qd / SIGN_SMOOTHING_RAD_S) + par[FRICTION_VISCOUS] * qd)
    lag = r.T @ (jac[:3] @ dq)
    for i in range(3):
        fs[TARGET_OFFSET + i] = fs[GEOMETRY_OFFSET + i] + lag[i] if par[GEOMETRY_ON] == 1.0 else lag[i]


@numba.njit(cache=True)
def _solve(
    fs: np.ndarray,
    ist: np.ndarray,
    par: np.ndarray,
    tab: np.ndarray,
    rows: np.ndarray,
    k_guided: float,
    c_total: np.ndarray,
    targets: np.ndarray,
    centre: np.ndarray,
    filled: np.ndarray,
    bins: np.ndarray,
) -> np.ndarray:  # pragma: no cover (compiled)
    """The tip balance over ``targets``: :meth:`TipContactSolver.run`; its rows."""
    n = int(par[N_GRID])
    bounds = (par[BOUNDS], par[BOUNDS + 1], par[BOUNDS + 2], par[BOUNDS + 3])
    state = fs[SOLVER : SOLVER + 8]
    out, touching, j = run_samples(
        targets,
        par[SERVO_GAIN],
        state,
        ist[TOUCHING] == 1,
        ist[BRACKET],
        par[TAN_BETA],
        bounds,
        tab[0, :n],
        rows,
        c_total,
        k_guided,
        centre,
        filled,
        bins,
        par[BIN_M],
    )
    ist[TOUCHING] = 1 if touching else 0
    ist[BRACKET] = j
    return out


@numba.njit(cache=True)
def _delayed(
    ist: np.ndarray, delay: np.ndarray, t_s: float, x: float, y: float, z: float, delay_s: float
) -> tuple[float, float, float]:  # pragma: no cover (compiled)
    """The servo target (m, task frame) as it was ``delay_s`` before ``t_s``, after recording ``(x, y, z)`` at ``t_s``.

    :class:`~drillgym.envs.effects.timing.DelayLine`'s ``push`` and ``read``: linear interpolation between
    samples, the first sample before it.
    """
    n = ist[DELAY_COUNT]
    if n == delay.shape[0]:  # full: keep the newest half
        keep = n // 2
        delay[:keep] = delay[n - keep : n].copy()
        n = keep
    delay[n, 0], delay[n, 1], delay[n, 2], delay[n, 3] = t_s, x, y, z
    n += 1
    ist[DELAY_COUNT] = n
    t_read = t_s - delay_s
    if t_read <= delay[0, 0]:
        return delay[0, 1], delay[0, 2], delay[0, 3]
    j = np.searchsorted(delay[:n, 0], t_read, side="right")
    if j >= n:
        return delay[n - 1, 1], delay[n - 1, 2], delay[n - 1, 3]
    w = (t_read - delay[j - 1, 0]) / (delay[j, 0] - delay[j - 1, 0])
    a, b = delay[j - 1], delay[j]
    return a[1] + w * (b[1] - a[1]), a[2] + w * (b[2] - a[2]), a[3] + w * (b[3] - a[3])


@numba.njit(cache=True)
def _rtde_tcp(fs: np.ndarray, par: np.ndarray, row: np.ndarray) -> None:  # pragma: no cover (compiled)
    """The RTDE TCP (base frame, m) where the encoders put the servo-held tip of sample ``row``."""
    o = R_BASE_TASK
    x, y, z = row[3], row[4], row[5]
    if par[GEOMETRY_ON] == 1.0:
        x, y, z = x - fs[GEOMETRY_OFFSET], y - fs[GEOMETRY_OFFSET + 1], z - fs[GEOMETRY_OFFSET + 2]
    for i in range(3):
        fs[RTDE_TCP + i] = par[ENTRY_BASE + i] + (par[o + 3 * i] * x + par[o + 3 * i + 1] * y + par[o + 3 * i + 2] * z)


@numba.njit(cache=True)
def _c_total(fs: np.ndarray, par: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    """Arm + drill compliance (3x3, m/N, task axes)."""
    c = np.empty((3, 3))
    for i in range(3):
        for k in range(3):
            c[i, k] = fs[C_ROBOT + 3 * i + k] + par[C_TOOL + 3 * i + k]
    return c


@numba.njit(cache=True)
def advance(  # noqa: C901 (one step, in the env's order)
    fs: np.ndarray,
    ist: np.ndarray,
    pend: np.ndarray,
    par: np.ndarray,
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
    """One agent step of an episode's arrays (:class:`KernelArrays`, in order) for ``command``, in place.

    ``command``: the correction (3, m, base frame) and the feed scale; ``noise``: standard normals, the F/T's
    (5x6, row-major) then the tracker's (3, read when its sample is new). Sets ``ist[TERMINATED]``,
    ``ist[TRUNCATED]`` and, on a singular Jacobian, ``ist[SINGULAR]`` (the state is then not advanced
    further). Called as ``advance(*arrays, command, noise, out)``: handing numba the ten arrays one by one
    costs 0.7 µs per call, the :class:`KernelArrays` tuple itself 1.6 µs (a trivial kernel of each form).
    """
    # queue the command; it applies after the latency
    npend = ist[PENDING]
    pend[npend, 0] = fs[T_S] + par[LATENCY_S]
    pend[npend, 1:4] = command[:3]
    pend[npend, 4] = command[3]
    ist[PENDING] = npend + 1
    if par[SOFTENING] > 0.0:
        _soften(fs, ist, par)
    if par[BACKLASH_HALF] > 0.0:
        _backlash(fs, par, chains)
    if par[FRICTION_ON] == 1.0:
        _friction_lag(fs, ist, pend, par)
    if par[SPINDLE_SAG] > 0.0:  # SpindleSag.begin_step: the speed from the last sample's cutting torque
        fs[SPINDLE_SHARE] = max(1.0 - par[SPINDLE_SAG] * abs(fs[SAMPLE + 9]), MIN_SPEED_SHARE)
    rtde_time = math.floor((fs[T_S] + CONTROL_DT_S) * RTDE_RATE_HZ + 1e-9) / RTDE_RATE_HZ
    c_total = _c_total(fs, par)
    nb = int(par[N_BINS])
    hole_c, hole_f = centre[:nb], filled[:nb]
    frows, k_guided = _prepare(fs, ist, pend, par, tab, rows)
    cx, cy, cz = _servo_xyz(fs, par)
    n = SUBSTEPS_PER_STEP
    targets = np.empty((n, 3))
    smp = np.empty((n, 13))
    done = 0
    rtde_k = -1
    t_s = fs[T_S]
    for k in range(n):
        t_next = t_s + PHYSICS_DT_S
        while ist[PENDING] > 0 and pend[0, 0] <= t_next + 1e-12:
            fs[CORRECTION : CORRECTION + 3] = pend[0, 1:4]
            scale = pend[0, 4]
            for r in range(ist[PENDING] - 1):
                pend[r] = pend[r + 1]
            ist[PENDING] -= 1
            if scale != fs[FEED_SCALE]:
                if k > done:
                    smp[done:k] = _solve(
                        fs, ist, par, tab, frows, k_guided, c_total, targets[done:k], hole_c, hole_f, bins
                    )
                    done = k
                fs[FEED_SCALE] = scale
                fs[T_S] = t_s
                frows, k_guided = _prepare(fs, ist, pend, par, tab, rows)
            cx, cy, cz = _servo_xyz(fs, par)
        phase = ist[PHASE]
        s = _path_advance(fs, ist, par[DEPTH], par[FEED_M_S])
        if t_s <= rtde_time < t_next:
            rtde_k = k
        if par[EXTRA_LATENCY] > 0.0:
            targets[k, 0], targets[k, 1], targets[k, 2] = _delayed(
                ist, delay, t_next, cx, cy, cz + s, par[EXTRA_LATENCY]
            )
        else:
            targets[k, 0], targets[k, 1], targets[k, 2] = cx, cy, cz + s
        out[k, OUT_T_S] = t_next
        out[k, OUT_PHASE] = phase
        out[k, OUT_DEPTH_CMD] = s
        t_s = t_next
    if n > done:
        smp[done:n] = _solve(fs, ist, par, tab, frows, k_guided, c_total, targets[done:n], hole_c, hole_f, bins)
    fs[T_S] = t_s
    fs[SAMPLE : SAMPLE + 13] = smp[n - 1]
    o = R_BASE_TASK
    if rtde_k >= 0:  # the RTDE sample saw the servo-held tip before sample rtde_k
        _rtde_tcp(fs, par, smp[rtde_k - 1] if rtde_k > 0 else smp[n - 1])
    # F/T readings: the true wrench at the sensor, noise, quantisation
    arm = par[SENSOR_ARM]
    dev_sum = 0.0
    lat_sum = 0.0
    mean = np.zeros(6)
    over = False
    for k in range(n):
        f0, f1, f2 = smp[k, 6], smp[k, 7], smp[k, 8]
        w = (f0, f1, f2, -arm * f1, arm * f0, smp[k, 9])
        for c in range(6):
            v = w[c] + par[FT_STD + c] * noise[6 * k + c] if par[FT_STD] > 0.0 else w[c]
            v = np.rint(v / FT_RESOLUTION[c]) * FT_RESOLUTION[c]
            out[k, OUT_FORCE + c] = v  # the force, then the torque (OUT_TORQUE)
            mean[c] = v if k == 0 else mean[c] + v
        f = OUT_FORCE
        if math.sqrt(out[k, f] ** 2 + out[k, f + 1] ** 2 + out[k, f + 2] ** 2) > par[FORCE_LIMIT]:
            over = True
        dev = math.hypot(smp[k, 0], smp[k, 1])
        out[k, OUT_STAGE] = smp[k, 11]
        out[k, OUT_DEVIATION] = dev
        out[k, OUT_TIP : OUT_TIP + 3] = smp[k, 0:3]
        out[k, OUT_CUTTING] = smp[k, 12]
        dev_sum += dev
        lat_sum += math.hypot(f0, f1)
    if over:
        ist[FAILURE] = 1
    if rtde_time >= fs[T_S] - 1e-12:
        _rtde_tcp(fs, par, smp[n - 1])
    for c in range(6):
        fs[FT_LAST + c] = out[n - 1, OUT_FORCE + c]
        fs[FT_MEAN + c] = mean[c] / n
    # the arm follows the servo target: one Newton step of IK, then J and the compliance at the new angles
    r_task = par[o : o + 9].reshape((3, 3))
    entry = par[ENTRY_BASE : ENTRY_BASE + 3]
    stiffness = par[STIFFNESS : STIFFNESS + 6]
    jac = fs[JACOBIAN : JACOBIAN + 36].reshape((6, 6))
    rigid = smp[n - 1, 3:6] - fs[GEOMETRY_OFFSET : GEOMETRY_OFFSET + 3] if par[GEOMETRY_ON] == 1.0 else smp[n - 1, 3:6]
    q = ik_step(fs[Q_MOTOR : Q_MOTOR + 6], jac, rigid, entry, r_task, chains[0])
    for i in range(6):
        if not math.isfinite(q[i]):
            ist[SINGULAR] = 1
            return
    fs[Q_MOTOR : Q_MOTOR + 6] = q
    jac, c_robot = jacobian_and_compliance(q, stiffness, r_task, chains[0])
    fs[JACOBIAN : JACOBIAN + 36] = jac.ravel()
    fs[C_ROBOT : C_ROBOT + 9] = c_robot.ravel()
    # the tracker: a new sample of the true (deflected) marker at its rate, against the nominal path
    stamp = math.floor(fs[T_S] * TRACKER_RATE_HZ + 1e-9) / TRACKER_RATE_HZ
    ist[TRACKER_NEW] = 0
    if stamp != fs[TRACKER_STAMP]:
        ist[TRACKER_NEW] = 1
        fs[TRACKER_STAMP] = stamp
        dq = joint_deflection(jac, smp[n - 1, 6:9], smp[n - 1, 9], r_task, stiffness)
        marker = frame_pose(q + dq, chains[1])[1]
        if par[MARKER_ON] == 1.0:
            marker = marker + fs[MARKER_OFFSET : MARKER_OFFSET + 3]
        for i in range(3):
            noisy = marker[i] + par[TRACKER_NOISE] * noise[6 * n + i] if par[TRACKER_NOISE] > 0.0 else marker[i]
            fs[TRACKER_READING + i] = noisy
    along = fs[PATH_S] - par[S_START]
    for i in range(3):
        planned = par[MARKER_START + i] + par[o + 3 * i + 2] * along  # + R_base_task · (0, 0, along)
        fs[TRACKER_ERROR + i] = fs[TRACKER_READING + i] - planned
    e0, e1, e2 = fs[TRACKER_ERROR], fs[TRACKER_ERROR + 1], fs[TRACKER_ERROR + 2]
    lat0 = par[o] * e0 + par[o + 3] * e1 + par[o + 6] * e2
    lat1 = par[o + 1] * e0 + par[o + 4] * e1 + par[o + 7] * e2
    fs[TRACKER_LATERAL] = math.hypot(lat0, lat1)
    for k in range(n):
        out[k, OUT_TRACKER_DEVIATION] = fs[TRACKER_LATERAL]
    fs[STEP_DEVIATION] = dev_sum / n
    fs[STEP_LATERAL] = lat_sum / n
    terminated = ist[PHASE] == DONE or ist[FAILURE] == 1
    ist[STEPS] += 1
    at_limit = fs[T_S] >= par[MAX_TIME_S] or ist[STEPS] >= MAX_EPISODE_STEPS
    ist[TERMINATED] = 1 if terminated else 0
    ist[TRUNCATED] = 1 if (not terminated) and at_limit else 0


@numba.njit(cache=True)
def advance_batch(
    fs: np.ndarray,
    ist: np.ndarray,
    pend: np.ndarray,
    par: np.ndarray,
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
) -> None:  # pragma: no cover (compiled)
    """:func:`advance` for every episode of N episodes' arrays (each with the episode as first axis).

    The step's rows go to ``record[i]`` from row ``recorded[i]`` on, which advances by five (the caller
    sizes ``record`` for the longest episode).
    """
    n = SUBSTEPS_PER_STEP
    for i in range(fs.shape[0]):
        k = recorded[i]
        advance(
            fs[i], ist[i], pend[i], par[i], tab[i], rows[i], chains[i], centre[i], filled[i], bins[i], delay[i],
            command[i], noise[i], record[i, k : k + n],
        )  # fmt: skip
        recorded[i] = k + n


@numba.njit(cache=True)
def advance_open_loop(
    fs: np.ndarray,
    ist: np.ndarray,
    pend: np.ndarray,
    par: np.ndarray,
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
    """:func:`advance` through ``commands`` (T, 4) until the episode ends, without noise; the steps taken.

    Sample rows go to ``out`` (5 T, :data:`OUT_COLUMNS`); after each step the motor angles (rad) to
    ``q_motor[k]`` (T, 6) and the tracker reading (m, base frame) to ``tracker[k]`` (T, 3). Stops at a
    singular Jacobian with ``ist[SINGULAR]`` set (that step not counted).
    """
    n = SUBSTEPS_PER_STEP
    noise = np.zeros(6 * n + 3)
    for k in range(commands.shape[0]):
        advance(
            fs, ist, pend, par, tab, rows, chains, centre, filled, bins, delay, commands[k], noise,
            out[n * k : n * k + n],
        )  # fmt: skip
        if ist[SINGULAR] == 1:
            return k
        q_motor[k] = fs[Q_MOTOR : Q_MOTOR + 6]
        tracker[k] = fs[TRACKER_READING : TRACKER_READING + 3]
        if ist[TERMINATED] == 1 or ist[TRUNCATED] == 1:
            return k + 1
    return commands.shape[0]
