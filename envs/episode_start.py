"""An episode's named state and parameters (:mod:`drillgym.envs.episode_state`) at its start, from the reset env.

``reset`` builds the episode in the env's Python objects (the cell, the path, the tip balance, the command queue,
the sensors); :func:`start_records` writes what they hold into an episode's records, which the compiled step
(:mod:`drillgym.envs.compiled_step`) and the batched env (:mod:`drillgym.envs.batched`) advance from there.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from drillgym.envs import step_kernel as sk
from drillgym.envs.cell import SimCell
from drillgym.envs.drilling.force_model import EngagementTable


def table_rows(table: EngagementTable, depth_profile: np.ndarray | None = None) -> np.ndarray:
    """The force table as :data:`~drillgym.envs.step_kernel.TABLE_ROWS` rows, with the depth profile's factors."""
    n = table.depth_m.shape[0]
    tab = np.zeros((sk.TABLE_ROWS, n))
    tab[0, :n] = table.depth_m
    tab[1:5, :n] = table.edge.T
    tab[5:9, :n] = table.per_chip.T
    tab[9, :n] = table.engaged_fraction
    tab[10, :n] = 1.0 if depth_profile is None else depth_profile
    return tab


def episode_params(p: np.void, env: Any) -> None:
    """Write an episode's constant parameters (a :data:`~drillgym.envs.episode_state.PARAMS` record) for ``env``'s cell as it is now."""
    cell: SimCell = env.cell
    sc, solver, geo = cell.scenario, cell.solver, cell.geometry
    p["latency_s"] = env.scenario.latency_s
    p["servo_gain"] = cell.servo_gain
    p["tan_beta"] = solver.tan_beta
    p["k_lat_n"] = solver.k_lat_n
    p["guidance_exponent"] = solver.guidance_exponent
    p["wall_floor"] = solver.wall_floor
    p["wall_length_m"] = solver.wall_length_m
    p["force_scale"] = solver.force_scale
    p["tracker_noise_m"] = env.tracker.noise_m
    p["force_limit_n"] = env.scenario.force_limit_n
    p["sensor_arm_m"] = cell.sensor_arm_m
    p["depth_m"] = sc.depth_m
    p["feed_m_s"] = sc.feed_m_s
    p["max_time_s"] = env.max_time_s
    p["n_lips"] = geo.n_lips
    p["rev_per_s"] = sc.spindle_rpm / 60.0
    p["sin_kappa"] = math.sin(geo.kappa_rad)
    p["R_base_task"] = cell.R_base_task
    p["entry_base_m"] = cell.entry_base_m
    p["C_tool"] = cell.C_tool
    p["stiffness_nm_rad"] = cell.joints.stiffness_nm_rad
    p["marker_start_base_m"] = env.marker_start_base
    p["s_start_m"] = env.s_start_m
    p["stage_bounds_m"] = solver._bounds
    p["ft_std"] = env.ft._noise_std
    p["n_grid"] = solver.grid.shape[0]
    p["n_bins"] = cell.hole.filled.shape[0]
    p["bin_m"] = cell.hole.bin_m
    p["omega_rad_s"] = 2.0 * math.pi * sc.spindle_rpm / 60.0
    if cell.geometry_offset_task_m is not None:  # the offsets themselves are state (start_state)
        p["geometry_on"] = p["target_offset_on"] = True
    if cell.marker_offset_base_m is not None:
        p["marker_on"] = True
    p["entry_guidance"] = solver.entry_guidance
    effects = [] if env.effects is None else env.effects.effects
    for e in effects:
        e.set_kernel_params(p)


def start_state(s: np.void, pend: np.ndarray, env: Any) -> None:
    """Write the episode's state as ``env``'s objects hold it (a :data:`~drillgym.envs.episode_state.STATE` record) and its command queue."""
    cell, solver = env.cell, env.cell.solver
    s["t_s"] = env.t_s
    s["path_m"] = env.path.s_m
    s["feed_scale"] = env.feed_scale
    s["correction_base_m"] = env.correction_base_m
    s["tip_balance"] = [*solver.rigid, *solver.tip, solver.bottom_z, solver.depth_local]
    s["rtde_tcp_base_m"] = env.rtde_tcp_base
    s["tracker_stamp_s"] = env.tracker_stamp
    s["tracker_reading_base_m"] = env.tracker_reading
    s["q_motor_rad"] = cell.q_motor_rad
    s["jacobian"] = cell.J_tcp
    s["c_robot_m_n"] = cell.C_robot
    s["force_scale_now"] = solver.force_scale
    s["spindle_share"] = cell.spindle_rpm / cell.scenario.spindle_rpm
    if cell.geometry_offset_task_m is not None:
        s["geometry_offset_task_m"] = cell.geometry_offset_task_m
    if cell.marker_offset_base_m is not None:
        s["marker_offset_base_m"] = cell.marker_offset_base_m
    s["target_offset_task_m"] = s["geometry_offset_task_m"]
    for e in [] if env.effects is None else env.effects.effects:
        e.load_kernel_state(s)
    smp = cell.sample
    s["sample"] = [
        *smp.tip,
        *smp.rigid,
        *smp.force,
        smp.torque_axis,
        smp.depth_local,
        smp.stage,
        1.0 if smp.cutting else 0.0,
    ]
    s["phase"] = int(env.path.phase)
    s["touching"] = solver.touching
    s["bracket"] = solver._j
    s["failure"] = env.failure is not None
    s["steps"] = env.steps
    s["pending"] = len(env.pending)
    for k, (t_apply, corr, scale) in enumerate(env.pending):
        pend[k, 0] = t_apply
        pend[k, 1:4] = corr
        pend[k, 4] = scale
