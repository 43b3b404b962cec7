"""``li2023``-family episodes on the batched engine, controller and cell stepped together in compiled code.

:func:`run_steps` is :func:`drillgym.controllers.rollout.run_batch`'s loop for one stacked ``li2023`` controller
(optionally under a slow entry) driving every slot of a :class:`~drillgym.envs.batched.BatchedDrillEnv`, step after
step, without a Python call per step: the controller's filter windows and its online correction
(:func:`~drillgym.controllers.li2023_step.online_into`), its action (:func:`~drillgym.controllers.li2023_step.actions_into`,
:func:`~drillgym.controllers.feed_schedule.add_entry_feed`), the action's check and scaling, the cell's step
(:func:`drillgym.envs.step_kernel.advance_batch`), the reward (:func:`drillgym.envs.reward.batch_rewards_into`), the
limits and the next observation (:func:`drillgym.envs.views.observation_rows`, cast to float32). Each is the function
the Python loop calls, or its arithmetic term for term, so every number is the Python loop's bit for bit
(``tests/controllers/test_closed_loop.py``).

It returns to Python at the events that need Python, with the reason (the ``STOP_*`` codes): a compensation point
(li2023's PID estimate reads the robot's Jacobian through its Python model), a refill of an episode's normals (its
generator), an episode's end (its metrics and info), a singular Jacobian or a bad action (the errors). The caller
handles the event and calls again; the loop resumes where it stopped.

Units: SI; frames: base unless named.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from drillgym.controllers.feed_schedule import add_entry_feed
from drillgym.controllers.li2023_step import actions_into, online_into
from drillgym.envs.constants import CONTROL_DT_S, FEED_OVERRIDE_LOG2_MAX, MAX_CORRECTION_M
from drillgym.envs.observation import OBS_COLUMN
from drillgym.envs.reward import batch_rewards_into
from drillgym.envs.step_kernel import advance_batch
from drillgym.envs.views import observation_rows

STOP_DONE, STOP_POINT, STOP_REFILL, STOP_ENDED, STOP_SINGULAR, STOP_BAD_ACTION, STOP_FULL = range(7)
"""Why :func:`run_steps` returned: every episode has ended; a compensation point is due (before this step's
action); a running episode's normals need a refill (this step's actions taken, before its step); episodes ended at the step just taken (in
``ended``); a singular Jacobian (the step taken, the rewards not); a non-finite action (nothing stepped); the reward
rows are full."""

_FT_MEAN = OBS_COLUMN["ft_wrench_mean"]
_TCP_ERROR = OBS_COLUMN["tcp_error_base_m"]
_DEPTH = OBS_COLUMN["path_depth_m"]
_Q = OBS_COLUMN["q_rad"]
_TRACKER_ERROR = OBS_COLUMN["tracker_error_base_m"]
_TRACKER_VALID = OBS_COLUMN["tracker_valid"]


@numba.njit(cache=True)
def _act(obs32: np.ndarray, counters: np.ndarray, ctl: tuple, actions: np.ndarray) -> bool:  # pragma: no cover
    """This step's actions into ``actions`` (li2023's ``act_batch``, then the slow entry's); False: a point is due.

    ``ctl`` and ``counters`` as :func:`run_steps` takes them.

    The filter windows take the observation first; a compensation point due at this step and not yet taken
    (``counters[1]``) stops before anything else (the caller takes it, then calls again).
    """
    (force_window, tcp_window, p_times, p_corr, p_ring, xp, fp, sizes, model_of, lateral, rot, c_tool, y_gain, entry_m,
     entry_offset, switches, reals, per_point) = ctl  # fmt: skip
    n = obs32.shape[0]
    step = counters[0]
    slot = step % force_window.shape[0]
    for i in range(n):
        for k in range(3):
            force_window[slot, i, k] = obs32[i, _FT_MEAN + k]
            tcp_window[slot, i, k] = obs32[i, _TCP_ERROR + k]
    online_on = switches[0] != 0
    if online_on and step % per_point[0] == 0 and counters[1] == 0:
        return False
    counters[1] = 0
    online = np.zeros((n, 3))
    if online_on:
        online_into(p_times, p_corr, p_ring, step * CONTROL_DT_S + CONTROL_DT_S, reals[1], online)
    counters[0] = step + 1
    depth = np.empty(n)
    for i in range(n):
        depth[i] = obs32[i, _DEPTH]
    actions_into(depth, switches[1] != 0, xp, fp, sizes, model_of, lateral, rot, c_tool, online, y_gain,
                 switches[2] != 0, switches[3] != 0, reals[0], np.empty((n, 3)), actions)  # fmt: skip
    if switches[4] != 0:
        add_entry_feed(actions, obs32[:, _DEPTH], entry_m, entry_offset)
    return True


@numba.njit(cache=True)
def _command(actions: np.ndarray, two: np.ndarray, a: np.ndarray, command: np.ndarray) -> bool:  # pragma: no cover
    """The env's action check and scaling of every row; False (nothing written) if any action is not finite.

    Writes ``a``, the actions clipped to [-1, 1] (float64), and ``command``: the correction (m) and the feed scale.
    """
    for i in range(actions.shape[0]):
        for k in range(4):
            if not math.isfinite(actions[i, k]):
                return False
    for i in range(actions.shape[0]):
        for k in range(4):
            v = np.float64(actions[i, k])
            a[i, k] = -1.0 if v < -1.0 else (1.0 if v > 1.0 else v)
        for k in range(3):
            command[i, k] = MAX_CORRECTION_M * a[i, k]
        command[i, 3] = math.pow(two[0], FEED_OVERRIDE_LOG2_MAX * a[i, 3])
    return True


@numba.njit(cache=True)
def _ends(
    state: np.ndarray, running: np.ndarray, max_episode_steps: int, limit_steps: bool, ended: np.ndarray
) -> bool:  # pragma: no cover
    """Which running episodes ended at this step (``ended``; the step limit truncates as the env's step does); any."""
    any_ended = False
    for i in range(state.shape[0]):
        s = state[i]
        done = s.terminated and running[i]
        cut = s.truncated and running[i]
        if limit_steps and running[i] and not done and s.steps >= max_episode_steps:
            cut = True
            s.truncated = True
        ended[i] = done or cut
        any_ended = any_ended or ended[i]
    return any_ended


@numba.njit(cache=True)
def _observe(
    state: np.ndarray,
    params: np.ndarray,
    recorded: np.ndarray,
    tracker_fitted: bool,
    obs64: np.ndarray,
    obs32: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """The batch's observation (:func:`~drillgym.envs.views.observation_rows`) into ``obs32``, cast as numpy casts."""
    tracking = np.empty(state.shape[0], dtype=np.bool_)
    for i in range(state.shape[0]):
        tracking[i] = recorded[i] > 0
    observation_rows(state, params, tracking, tracker_fitted, obs64)
    for i in range(state.shape[0]):
        for k in range(obs64.shape[1]):
            obs32[i, k] = np.float32(obs64[i, k])


@numba.njit(cache=True)
def _keep_log_rows(
    k: int,
    running: np.ndarray,
    command: np.ndarray,
    obs32: np.ndarray,
    state: np.ndarray,
    held: np.ndarray,
    valid: np.ndarray,
    logged: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """What step ``k`` held for each running episode's log (:data:`drillgym.controllers.step_log.HELD`).

    As :meth:`~drillgym.controllers.step_log.StepLog.log_step` keeps it from the step's command and observation.
    """
    for i in range(running.shape[0]):
        if not running[i]:
            continue
        row, s = held[i, k], state[i]
        ok = obs32[i, _TRACKER_VALID] > 0.5
        for c in range(4):
            row[c] = command[i, c]
        for c in range(6):
            row[4 + c] = obs32[i, _Q + c]
        for c in range(3):
            row[10 + c] = s.rtde_tcp_base_m[c]
            row[13 + c] = s.tracker_reading_base_m[c] if ok else np.nan
            row[16 + c] = obs32[i, _TRACKER_ERROR + c]
        valid[i, k] = ok
        logged[i] = k + 1


@numba.njit(cache=True)
def run_steps(
    env: tuple,
    command: np.ndarray,
    noise: np.ndarray,
    refill_at: int,
    noisy: np.ndarray,
    record: np.ndarray,
    recorded: np.ndarray,
    active: np.ndarray,
    weights: np.ndarray,
    prev_action: np.ndarray,
    peak_lateral_n: np.ndarray,
    max_episode_steps: int,
    limit_steps: bool,
    tracker_fitted: bool,
    obs64: np.ndarray,
    obs32: np.ndarray,
    ctl: tuple,
    counters: np.ndarray,
    reward_rows: np.ndarray,
    ended: np.ndarray,
    actions: np.ndarray,
    two: np.ndarray,
    log: tuple,
) -> int:  # pragma: no cover (compiled)
    """Step every active episode until an event (a ``STOP_*`` code, returned).

    Args:
        env: the batch's :class:`~drillgym.envs.step_kernel.KernelArrays`, in order (state, params, pend, tab, rows,
            chains, centre, filled, bins, delay).
        command: (N, 4) the step's command, written (correction m, feed scale).
        noise: (N, M) each episode's normals (:class:`~drillgym.envs.noise_ahead.NormalsAhead` rows).
        refill_at: an episode whose ``noise_at`` exceeds this may read past its row: its normals need a refill.
        noisy: (N,) whether each episode reads normals at all.
        record: the batch's record of samples (N, rows, columns).
        recorded: (N,) each episode's recorded rows.
        active: (N,) which episodes run; an ended one drops out.
        weights: the reward's four weights (:meth:`~drillgym.envs.reward.RewardWeights.vector`).
        prev_action: (N, 4) the batch's last actions, updated.
        peak_lateral_n: (N,) the running peaks of the lateral force (N), updated.
        max_episode_steps: the batch's step limit.
        limit_steps: whether that limit is below the registration's (the env's step then truncates at it).
        tracker_fitted: whether the cell has a tracker.
        obs64: (N, 33) float64 scratch for the observation.
        obs32: (N, 33) float32, the current observation (what the controller reads).
        ctl: the controller's arrays: ``(force window (W, N, 3), TCP error window (W, N, 3), point times (P,),
            point corrections (P, N, 3), point ring (2,), offline models' depths (M, L), their forces (M, L, 2),
            sizes (M,), model_of (N,), lateral (K, 3, 3), R (K, 3, 3), C_tool (K, 3, 3), y gain (1,) or (N,),
            entry depth (E,), entry offset (E,), switches (5,) int: online, offline, y any, y all, slow entry;
            reals (2,): max correction (m), point period (s); steps per point (1,) int)``.
        counters: int64 ``[controller step, point taken at this step, loop step, this step's actions taken]``.
        reward_rows: (S, N) each step's rewards, row ``counters[2]`` written next.
        ended: (N,) bool, written: the episodes that ended at the last step.
        actions: (N, 4) float32, written: the controller's last actions.
        two: ``[2.0]``: the feed scale's base, read at run time so that the power is the C library's ``pow``, as
            Python's ``2.0 ** x`` computes it (a constant base may be compiled as another function).
        log: ``(on (1,) bool, held (N, S, H), valid (N, S), logged (N,))``: whether to keep each step's log rows,
            and the episode logs' arrays (:class:`~drillgym.controllers.step_log.StepLog`), filled at row
            ``counters[2]`` of each step.
    """
    log_on, held, valid, logged = log
    state, params, pend, tab, rows, chains, centre, filled, bins, delay = env
    n = state.shape[0]
    a = np.empty((n, 4))
    running = np.empty(n, dtype=np.bool_)
    deviation, lateral_n = np.empty(n), np.empty(n)
    terms, reward = np.empty((4, n)), np.empty(n)
    while True:
        if not active.any():
            return STOP_DONE
        if counters[2] >= reward_rows.shape[0]:
            return STOP_FULL
        if counters[3] == 0 and not _act(obs32, counters, ctl, actions):  # once a step (kept through a refill)
            return STOP_POINT
        counters[3] = 1
        if not _command(actions, two, a, command):  # the env's step (BatchedDrillEnv.step) from here
            return STOP_BAD_ACTION
        for i in range(n):  # after the action's check, as the env's step does
            if active[i] and noisy[i] and state[i].noise_at > refill_at:
                return STOP_REFILL
        counters[3] = 0
        running[:] = active
        advance_batch(state, params, pend, tab, rows, chains, centre, filled, bins, delay, command, noise, record,
                      recorded, running)  # fmt: skip
        for i in range(n):
            if state[i].singular:
                return STOP_SINGULAR
            deviation[i] = state[i].step_deviation_m
            lateral_n[i] = state[i].step_lateral_n
        batch_rewards_into(weights, deviation, lateral_n, a, prev_action, peak_lateral_n, running, terms, reward)
        reward_rows[counters[2]] = reward
        counters[2] += 1
        prev_action[:] = a
        any_ended = _ends(state, running, max_episode_steps, limit_steps, ended)
        _observe(state, params, recorded, tracker_fitted, obs64, obs32)
        if log_on[0]:
            _keep_log_rows(counters[2] - 1, running, command, obs32, state, held, valid, logged)
        if any_ended:
            return STOP_ENDED
