"""An episode's state and constant parameters as named fields, with a leading episode axis.

The compiled step (:mod:`drillgym.envs.step_kernel`) works on two NumPy structured arrays of shape ``(N,)``:
``state`` (:data:`STATE`, what a step changes) and ``params`` (:data:`PARAMS`, what is fixed for the episode).
Numba takes them as it takes plain arrays: ``state[i]`` is episode ``i``'s record, passed by reference, whose
fields read and write in place (``s.t_s += dt``, ``s.q_motor_rad[:] = q``). From Python, ``state["t_s"]`` is a
view of every episode's time and ``state[0]["jacobian"]`` episode 0's 6x6 Jacobian. The single env holds N = 1,
the batched env (:mod:`drillgym.envs.batched`) N.

Each field is declared once, below, with its unit and frame: :data:`STATE_FIELDS` and :data:`PARAM_FIELDS` are
the documentation, the dtypes are built from them. Flags are booleans, counts and codes ``int64``, the rest
``float64``. Frames: "base" the robot base, "task" the hole's frame (z along the planned axis), "sensor" the
F/T sensor's.
"""

from __future__ import annotations

import math
from collections import namedtuple
from typing import Any

import numpy as np

from drillgym.envs.drilling.contact_kernel import ROW_SIZE, STATE_SIZE
from drillgym.envs.effects.registry import EFFECTS
from drillgym.envs.record_fields import Field, flag_field, float_field, int_field

_f, _i, _b = float_field, int_field, flag_field


CORE_STATE_FIELDS: tuple[Field, ...] = (
    _f("t_s", "Simulated time (s)."),
    _f("path_m", "Nominal depth along the planned axis (m)."),
    _f("feed_scale", "Feed override in effect (-)."),
    _f("correction_base_m", "Tip correction in effect (m, base frame).", 3),
    _f(
        "tip_balance",
        "The tip balance's state (:data:`~drillgym.envs.drilling.contact_kernel.STATE_SIZE`): rigid tip (3), "
        "true tip (3), deepest point cut, local depth (m, task frame).",
        STATE_SIZE,
    ),
    _f("key_chip_m", "Chip thickness the cached force rows were made for (m; NaN: none yet)."),
    _f("key_scale", "Specimen hardness factor the cached force rows were made for (-)."),
    _f("rtde_tcp_base_m", "The RTDE TCP position (m, base frame).", 3),
    _f("ft_last", "Latest F/T reading (N and N·m, sensor frame).", 6),
    _f("ft_mean", "Mean of the step's F/T readings (N and N·m, sensor frame).", 6),
    _f("tracker_stamp_s", "Time stamp of the latest tracker sample (s; -1 before the first)."),
    _f("tracker_reading_base_m", "Latest tracker reading (m, base frame).", 3),
    _f(
        "tracker_error_base_m",
        "Tracker reading minus where a rigid arm on the nominal path puts the marker (m, base frame).",
        3,
    ),
    _f("tracker_lateral_m", "Lateral part of the tracker error (m, task xy)."),
    _f("step_deviation_m", "Mean true tip deviation over the step's samples (m)."),
    _f("step_lateral_n", "Mean true lateral force over the step's samples (N)."),
    _f("q_motor_rad", "Motor-side joint angles (rad).", 6),
    _f("jacobian", "TCP Jacobian at ``q_motor_rad`` (base axes; rows: linear (m/rad), angular (rad/rad)).", 6, 6),
    _f(
        "tcp_pose_base",
        "The TCP's pose at ``tcp_pose_q_rad``, computed with the Jacobian, which the next IK step reads: rotation "
        "(9, row-major), then origin (3, m); base frame.",
        12,
    ),
    _f("tcp_pose_q_rad", "The motor angles ``tcp_pose_base`` is for (rad; NaN: none yet).", 6),
    _f("c_robot_m_n", "Arm compliance at the TCP (m/N, task axes).", 3, 3),
    _f(
        "sample",
        "The latest sample's row (:data:`~drillgym.envs.drilling.contact_kernel.ROW_SIZE`): tip (3), rigid tip "
        "(3), force (3, N), torque about the axis (N·m), local depth (m), stage, cutting (0/1); task frame.",
        ROW_SIZE,
    ),
    _f(
        "target_offset_task_m",
        "This step's shift of the servo target (m, task frame): the geometry offset plus, with joint friction, "
        "its servo lag (used where ``params.target_offset_on``).",
        3,
    ),
    _f("force_scale_now", "The force scale in effect: the specimen's, after thermal softening if on (-)."),
    _f("spindle_share", "The spindle's speed as a share of the scenario's (1 without spindle sag)."),
    _f(
        "geometry_offset_task_m",
        "Where the physical tool sits away from the controller's model (m, task frame; used where "
        "``params.geometry_on``): constant but for joint backlash, whose links move it.",
        3,
    ),
    _f("marker_offset_base_m", "The same for the tracker marker (m, base frame; used where ``params.marker_on``).", 3),
    _i("phase", "Path phase (:class:`~drillgym.envs.task.Phase`)."),
    _b("touching", "Whether the tip touched bone at the latest sample."),
    _i("bracket", "The depth grid's bracket of the latest root (warm start)."),
    _b("failure", "True once the measured force exceeded the limit."),
    _i("steps", "Agent steps taken."),
    _i("pending", "Commands queued in the command queue ``pend``."),
    _b("terminated", "The episode ended (drilled and retracted, or the force limit)."),
    _b("truncated", "The episode hit its time or step limit."),
    _b("singular", "The inverse kinematics met a singular Jacobian (the caller raises)."),
    _b("tracker_new", "This step's tracker sample is new (its noise was drawn)."),
    _i(
        "noise_at",
        "Next unread standard normal of the episode's noise buffer: a step reads the F/T's 30 there if it is noisy, "
        "then the tracker's 3 if it is noisy and its sample is new, and moves on past them.",
    ),
)
"""What a step changes, per episode, whatever effects the cell has."""

CORE_PARAM_FIELDS: tuple[Field, ...] = (
    _f("latency_s", "Command latency (s)."),
    _f("servo_gain", "Servo tracking gain per physics update (-)."),
    _f("tan_beta", "Tangent of the surface's slope at the entry (-)."),
    _f("k_lat_n", "Lateral cut stiffness times the axial advance per update (N)."),
    _f("guidance_exponent", "Exponent of the engaged share in the side guidance (-)."),
    _f("wall_floor", "Side guidance at the hole's wall start, as a share of full guidance (-)."),
    _f("wall_length_m", "Depth over which the wall's guidance builds up (m)."),
    _f("force_scale", "The specimen's hardness factor (-)."),
    _f("tracker_noise_m", "Tracker noise std (m; 0: noiseless)."),
    _f("force_limit_n", "F/T force magnitude that ends the episode (N)."),
    _f("sensor_arm_m", "Distance from the F/T sensor to the tip along the tool axis (m)."),
    _f("depth_m", "Hole depth (m)."),
    _f("feed_m_s", "Nominal feed (m/s)."),
    _f("max_time_s", "Episode time limit (s)."),
    _f("n_lips", "Cutting lips of the drill (-)."),
    _f("rev_per_s", "Spindle speed (rev/s)."),
    _f("sin_kappa", "Sine of the lips' half point angle (-)."),
    _f("R_base_task", "Rotation from the task frame to the base frame (-).", 3, 3),
    _f("entry_base_m", "The entry point (m, base frame).", 3),
    _f("C_tool", "Drill compliance at the tip (m/N, task axes).", 3, 3),
    _f("stiffness_nm_rad", "Joint stiffness (N·m/rad).", 6),
    _f("marker_start_base_m", "The tracker marker's model position at the start (m, base frame).", 3),
    _f("s_start_m", "Nominal depth at the start (m)."),
    _f("stage_bounds_m", "The stage bounds (m).", 4),
    _f("ft_std", "F/T noise std per axis (N and N·m).", 6),
    _i("n_grid", "Rows of the force table in use."),
    _i("n_bins", "Bins of the hole in use."),
    _f("bin_m", "Axial size of a hole bin (m)."),
    _b("geometry_on", "The cell has a geometry offset."),
    _b("marker_on", "The cell has a marker offset."),
    _b("target_offset_on", "The servo target is shifted (a geometry offset or joint friction)."),
    _f("entry_guidance", "Extra side guidance while the lips enter (share of full guidance at first touch)."),
    _f("omega_rad_s", "Spindle speed (rad/s)."),
)
"""What is fixed for an episode, whatever effects the cell has (set at reset from the cell and the scenario)."""

_COMPILED = [cls for cls in EFFECTS.values() if cls.__dict__.get("compiled", False)]
STATE_FIELDS: tuple[Field, ...] = CORE_STATE_FIELDS + tuple(f for cls in _COMPILED for f in cls.kernel_state)
"""What a step changes, per episode: the core's fields, then those the compiled effects declare (their state)."""
PARAM_FIELDS: tuple[Field, ...] = CORE_PARAM_FIELDS + tuple(f for cls in _COMPILED for f in cls.kernel_params)
"""What is fixed for an episode: the core's fields, then those the compiled effects declare (their parameters,
zero when the effect is off)."""


def _dtype(fields: tuple[Field, ...]) -> np.dtype:
    return np.dtype([(f.name, f.dtype, f.shape) for f in fields], align=True)


STATE = _dtype(STATE_FIELDS)
"""The state's record type."""
PARAMS = _dtype(PARAM_FIELDS)
"""The parameters' record type."""


def _scalar_view(fields: tuple[Field, ...], dtype: np.dtype) -> np.dtype:
    """``dtype``'s scalar fields alone, at their offsets: a view whose ``item()`` makes no array views."""
    scalars = [f for f in fields if f.shape == ()]
    offsets = dtype.fields
    assert offsets is not None
    spec: Any = {
        "names": [f.name for f in scalars],
        "formats": [f.dtype for f in scalars],
        "offsets": [offsets[f.name][1] for f in scalars],
        "itemsize": dtype.itemsize,
    }
    return np.dtype(spec)


def _tuple_of(name: str, fields: tuple[Field, ...]) -> Any:
    """A named tuple of ``fields``' scalars (built from the declarations, so typed ``Any``)."""
    return namedtuple(name, [f.name for f in fields if f.shape == ()])


STATE_SCALARS = _scalar_view(STATE_FIELDS, STATE)
"""The state's scalar fields (``state.view(STATE_SCALARS)[i].item()``: episode ``i``'s as Python numbers)."""


StateScalars: Any = _tuple_of("StateScalars", STATE_FIELDS)
"""One episode's scalar state fields as Python numbers, by name: ``StateScalars._make(view[i].item())``."""


STEP_SCALAR_NAMES = frozenset(
    {"t_s", "path_m", "feed_scale", "tracker_stamp_s", "step_deviation_m", "step_lateral_n", "phase", "failure"}
    | {"terminated", "truncated", "singular"}
)
"""The scalars every step reads back (time, path, the reward's inputs, how the episode stands)."""
_STEP_FIELDS = tuple(f for f in STATE_FIELDS if f.name in STEP_SCALAR_NAMES)
STEP_SCALARS = _scalar_view(_STEP_FIELDS, STATE)
"""A view of the state with :data:`STEP_SCALAR_NAMES` alone (cheaper to read than :data:`STATE_SCALARS`)."""
StepScalars: Any = _tuple_of("StepScalars", _STEP_FIELDS)
"""One episode's :data:`STEP_SCALAR_NAMES` as Python numbers: ``StepScalars._make(view[i].item())``."""


def new_state(n: int) -> np.ndarray:
    """``n`` episodes' state, zero but for ``key_chip_m`` and ``tcp_pose_q_rad`` (NaN: nothing cached yet)."""
    state = np.zeros(n, dtype=STATE)
    state["key_chip_m"] = math.nan
    state["tcp_pose_q_rad"] = math.nan
    return state


def new_params(n: int) -> np.ndarray:
    """``n`` episodes' parameters, all zero (every effect off)."""
    return np.zeros(n, dtype=PARAMS)
