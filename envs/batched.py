"""N drilling episodes stepped in lock-step: a native ``gymnasium.vector.VectorEnv``.

Each episode is the single env's (:class:`~drillgym.envs.drill_env.UR5BoneDrillEnv`) without unmodelled
effects or with compiled ones (``effects=``): the same scenario, the same seeded specimen and sensor noise, the
same physics, one compiled call (:func:`~drillgym.envs.step_kernel.advance_batch`) for all N per agent step, with
the state on arrays whose first axis is the episode (:mod:`drillgym.envs.episode_state`). Episode ``i`` of
``reset(seed=s)`` is the single env's ``reset(seed=s + i)``, and its records and metrics equal the single env's
(``tests/envs/test_batched.py``). Each episode's sensor noise comes from its own generator, drawn ahead in blocks
into a buffer the compiled step reads; when the episode ends its generator is put back where the single env's
step-by-step draws would have left it.

An episode that ends is reset in the same call (``autoreset_mode`` SAME_STEP): its last observation and
info are in ``infos["final_obs"]`` and ``infos["final_info"]`` (with the episode's metrics), as Gymnasium's
vector envs report them, and the next episode continues that slot's generator, as ``reset()`` without a
seed continues the single env's.

    env = BatchedDrillEnv(64)                       # the paper scenario; scenario arguments as for gym.make
    obs, infos = env.reset(seed=0)                  # obs: dict of (64, k) float32 arrays
    obs, reward, terminated, truncated, infos = env.step(actions)   # actions: (64, 4)

Per step, ``infos`` holds ``t_s``, ``phase``, ``deviation_m`` (the true tip's, privileged) and
``reward_terms`` as arrays; the single env's other privileged entries are in ``final_info`` at the end.

The episodes need not share a scenario: ``reset(options={"scenario": [changes_0, ..., changes_N-1]})`` changes
each slot's scenario arguments from this episode on, as the single env's ``reset(options={"scenario": ...})``
does (one dict: every slot's), so a batch can drill N different holes (a schedule residual's training does). The
slots must agree on whether the cell has a tracker (one observation layout). Likewise ``reset(options={"effects":
[spec_0, ..., spec_N-1]})`` puts each slot in its own cell of compiled effects (a cell drawn per episode), and
``BatchedDrillEnv(N, threads=T)`` spreads the compiled step's episodes over ``T`` threads (the same numbers).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from types import SimpleNamespace
from typing import Any

import numba
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from drillgym.envs import step_kernel as sk
from drillgym.envs.cell import chains_of
from drillgym.envs.compiled_step import episode_arrays
from drillgym.envs.constants import ACTION_DIM, CONTROL_DT_S, MAX_EPISODE_STEPS, SUBSTEPS_PER_STEP, scaled_rows
from drillgym.envs.drill_env import UR5BoneDrillEnv
from drillgym.envs.drilling.hole import centre_at
from drillgym.envs.effects.registry import build_effects, runs_compiled
from drillgym.envs.episode_state import new_params, new_state
from drillgym.envs.errors import UserError
from drillgym.envs.metrics import episode_metrics
from drillgym.envs.noise_ahead import NormalsAhead
from drillgym.envs.observation import observation_space
from drillgym.envs.reward import TERM_NAMES, batch_rewards_into, checked_action
from drillgym.envs.sample_record import OUT_COLUMNS, record_channels
from drillgym.envs.scenario import Scenario
from drillgym.envs.step_noise import NOISE_SIZE, is_noisy
from drillgym.envs.task import Phase
from drillgym.envs.views import observation_from_state, privileged_info

NOISE_BLOCK = 64 * NOISE_SIZE
"""Standard normals per episode drawn ahead (:class:`~drillgym.envs.noise_ahead.NormalsAhead`): 64 steps' worth."""


class BatchedDrillEnv(VectorEnv):
    """``num_envs`` episodes of one scenario in lock-step (see the module docstring).

    Args:
        num_envs: episodes stepped together (>= 1).
        max_episode_steps: truncate an episode after this many agent steps (default and upper bound: the
            registration's 4000, which the env applies itself); ``gym.make_vec`` passes the registration's.
        autoreset: True (Gymnasium's SAME_STEP): an ended episode's slot restarts in the same call; False: it
            stays ended (not stepped, reward 0, flags False) until the next :meth:`reset`, for running a set
            of seeded episodes once each (:attr:`active` says which still run).
        effects: an effect spec (:func:`drillgym.envs.effects.build_effects`, e.g. a cell of
            :data:`drillgym.envs.effects.cells.CELLS`) built afresh for every episode; compiled effects only
            (:attr:`Effect.compiled <drillgym.envs.effects.base.Effect.compiled>`), else a ``UserError``. A
            slot's own spec can be given at reset (``options={"effects": [...]}``).
        threads: CPU threads the compiled step spreads the episodes over (default 1; at most numba's
            ``NUMBA_NUM_THREADS``, the machine's CPUs unless set): the same numbers with any number
            (``tests/envs/test_batched_threads.py``). Worth it for large batches on an otherwise idle machine; a
            process that shares its cores (training workers, ``--workers``) keeps 1.
        **env_kwargs: the single env's arguments (scenario, ``cell_params``, ``bone_material``, reward
            weights); rendering is not available.
    """

    metadata = {"autoreset_mode": AutoresetMode.SAME_STEP}  # noqa: RUF012

    def __init__(
        self,
        num_envs: int,
        max_episode_steps: int | None = None,
        autoreset: bool = True,
        effects: str = "",
        threads: int = 1,
        **env_kwargs: Any,
    ) -> None:
        if not isinstance(num_envs, int) or num_envs < 1:
            raise UserError(f"num_envs={num_envs!r} must be an integer >= 1")
        most = int(getattr(numba.config, "NUMBA_NUM_THREADS", 1))  # set from the environment at numba's import
        if not isinstance(threads, int) or not 1 <= threads <= most:
            raise UserError(f"threads={threads!r} must be an integer in [1, {most}] (numba's NUMBA_NUM_THREADS)")
        self.threads = threads
        limit = MAX_EPISODE_STEPS if max_episode_steps is None else max_episode_steps
        if not isinstance(limit, int) or not 1 <= limit <= MAX_EPISODE_STEPS:
            raise UserError(f"max_episode_steps={max_episode_steps!r} must be an integer in [1, {MAX_EPISODE_STEPS}]")
        self.max_episode_steps = limit
        if env_kwargs.get("render_mode") is not None:
            raise UserError("BatchedDrillEnv does not render; use UR5BoneDrillEnv(render_mode='rgb_array')")
        self.num_envs = num_envs
        self.autoreset = autoreset
        self.effects = effects
        _check_compiled(effects)  # a bad spec fails here, not at the first reset
        self._slot_effects = [effects] * num_envs
        """Each slot's effect spec (the construction's, or the last reset's)."""
        self.envs = [UR5BoneDrillEnv(pybullet_world=False, **env_kwargs) for _ in range(num_envs)]
        first = self.envs[0]
        self.scenario = first.scenario
        """The scenario given at construction (each slot's own, after a reset that changes it: :meth:`scenario_of`)."""
        self.reward_weights = first.reward
        self._weights = self.reward_weights.vector()
        self.single_observation_space = observation_space()
        self.single_action_space = spaces.Box(-1.0, 1.0, (ACTION_DIM,), np.float32)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        n, cells = num_envs, [e.cell for e in self.envs]
        grid = max(c.solver.grid.shape[0] for c in cells)
        bins = max(c.hole.filled.shape[0] for c in cells)
        self.arrays = sk.KernelArrays(
            state=new_state(n),
            params=new_params(n),
            pend=np.zeros((n, sk.PENDING_ROWS, 5)),
            tab=np.zeros((n, sk.TABLE_ROWS, grid)),
            rows=np.zeros((n, grid, 4)),
            chains=np.stack([np.stack(chains_of(c.kin)) for c in cells]),
            centre=np.zeros((n, bins, 2)),
            filled=np.zeros((n, bins), dtype=bool),
            bins=np.full((n, 2), -1, dtype=np.int64),
            delay=np.zeros((n, 1, 4)),  # no effects: no delay line
        )
        self.state, self.params = self.arrays.state, self.arrays.params
        self.command = np.zeros((n, 4))
        self.normals = NormalsAhead(n, NOISE_BLOCK)
        """Each episode's sensor noise drawn ahead from its generator (the compiled step's ``noise``)."""
        self.record = np.zeros((n, _record_rows(first.max_time_s), OUT_COLUMNS))
        self.recorded = np.zeros(n, dtype=np.int64)
        self.prev_action = np.zeros((n, ACTION_DIM))
        self.peak_lateral_n = np.zeros(n)
        self.active = np.zeros(n, dtype=bool)
        """Which episodes are running (all after :meth:`reset`; with ``autoreset=False`` an ended one drops out)."""
        self._ready = False
        self.kernel_s = 0.0
        """Wall seconds spent in the compiled step since construction (the physics; the rest of a step is Python)."""

    # ------------------------------------------------------------------ episodes
    def _reset_one(self, i: int, seed: int | None, changes: Mapping[str, Any] | None = None) -> None:
        """Reset slot ``i`` (the single env's ``reset(seed=seed)``, with ``changes`` to its scenario) into the arrays."""
        env = self.envs[i]
        spec = self._slot_effects[i]
        if spec or env.effects is not None:
            env.set_effects(build_effects(spec) if spec else None)
        env.begin_episode(seed=seed, options={"scenario": dict(changes)} if changes else None)
        if env._kernel is None:
            raise UserError(f"effects {spec!r} do not all run in the compiled step; use UR5BoneDrillEnv")
        start = episode_arrays(env)
        for name in ("tab", "rows", "centre", "filled", "delay"):
            self._fit(name, getattr(start, name).shape[1:])
        self._fit_record(env.max_time_s)
        arrays = self.arrays
        for name in ("state", "params", "pend", "bins", "chains"):  # the chains: the slot's stick-out and marker
            getattr(arrays, name)[i] = getattr(start, name)[0]
        for name in ("tab", "centre", "filled", "delay"):  # padded to the batch's largest
            row, one = getattr(arrays, name)[i], getattr(start, name)[0]
            row[...] = 0
            row[tuple(slice(0, m) for m in one.shape)] = one
        self.recorded[i] = 0
        self.prev_action[i] = 0.0
        self.peak_lateral_n[i] = 0.0
        self.active[i] = True
        self.normals.restart(i, self.state["noise_at"])  # the generator was (re)seeded or is in step

    def _draw_ahead(self, running: np.ndarray) -> None:
        """Refill the normals of the running episodes that may read past their row in this step."""
        noise_at = self.state["noise_at"]
        for i in (running & (noise_at > self.normals.size - NOISE_SIZE)).nonzero()[0].tolist():
            if is_noisy(self.params[i]):
                self.normals.refill(i, self.envs[i].np_random, noise_at)

    def _fit(self, name: str, shape: tuple[int, ...]) -> None:
        """Grow array ``name`` (zero-padded, contents kept) so that each episode's row holds ``shape``."""
        self.arrays = self.arrays._replace(**{name: _grown(getattr(self.arrays, name), shape)})

    def _fit_record(self, max_time_s: float) -> None:
        """Grow the record (contents kept) so that an episode of ``max_time_s`` fits in its rows."""
        self.record = _grown(self.record, (_record_rows(max_time_s), OUT_COLUMNS))

    def reset(
        self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        """Reset every episode: ``seed`` (int: episode ``i`` gets ``seed + i``; or one seed per episode).

        ``options={"scenario": changes}``: scenario arguments changed from this episode on, one dict for every
        slot or a list of one per slot (validated first: a reset that raises changes nothing).
        """
        if seed is None or isinstance(seed, int):
            seeds: list[int | None] = [None if seed is None else seed + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise UserError(f"{len(seeds)} seeds for {self.num_envs} episodes")
        changes = self._scenario_changes(options)
        effects = self._effect_specs(options)
        for i, s in enumerate(seeds):
            spec = effects[i]
            if spec is not None:
                self._slot_effects[i] = spec
            self._reset_one(i, s, changes[i])
        self._ready = True
        return self._observation(), {}

    def _scenario_changes(self, options: Mapping[str, Any] | None) -> list[dict[str, Any] | None]:
        """Each slot's scenario changes from ``reset``'s options, every one validated before any slot resets."""
        opts = dict(options or {})
        unknown = sorted(set(opts) - {"scenario", "effects"})
        if unknown:
            raise UserError(
                f"reset(options=...): unknown key(s) {unknown}; BatchedDrillEnv takes 'scenario' (one dict, or a "
                "list of one per episode) and 'effects' (one effect spec, or a list of one per episode)"
            )
        per_slot = self._per_slot(opts.get("scenario"), Mapping, "scenario", "a dict")
        scenarios = [
            Scenario.from_kwargs(**{**env.scenario.to_dict(), **dict(c)}) if c else env.scenario
            for env, c in zip(self.envs, per_slot, strict=True)
        ]
        if any(sc.tracker != self.scenario.tracker for sc in scenarios):
            raise UserError(
                f"every episode of a batch has tracker={self.scenario.tracker} (its construction's): one observation"
            )
        return [dict(c) if c else None for c in per_slot]

    def _effect_specs(self, options: Mapping[str, Any] | None) -> list[str | None]:
        """Each slot's effect spec from ``reset``'s options (None: the slot keeps its own), all checked first."""
        per_slot = self._per_slot(dict(options or {}).get("effects"), str, "effects", "an effect spec")
        for spec in dict.fromkeys(c for c in per_slot if c):
            _check_compiled(spec)
        return per_slot

    def _per_slot(self, given: Any, kind: type, key: str, one: str) -> list[Any]:
        """A reset option for every slot: None (each keeps its own), one ``kind`` for all, or one per slot (or None)."""
        if given is None:
            return [None] * self.num_envs
        per_slot = [given] * self.num_envs if isinstance(given, kind) else list(given)
        if len(per_slot) != self.num_envs or not all(c is None or isinstance(c, kind) for c in per_slot):
            raise UserError(
                f"options[{key!r}] must be {one} or a list of {self.num_envs} (one per episode, or None), got {given!r}"
            )
        return per_slot

    def effects_of(self, i: int) -> str:
        """Episode ``i``'s effect spec (the construction's, or the last reset's)."""
        return self._slot_effects[i]

    def scenario_of(self, i: int) -> Scenario:
        """Episode ``i``'s scenario (the construction's, or the last reset's changes)."""
        return self.envs[i].scenario

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One agent step of every running episode (``actions``: (num_envs, 4) in [-1, 1]).

        Ended episodes are reset (``autoreset``) or drop out of :attr:`active`; a slot that is not active is not
        stepped (its action is still checked), its reward is 0 and its flags False.
        """
        if not self._ready:
            raise RuntimeError("step() before reset(); call reset() first")
        a = checked_action(actions, "state unchanged", self.num_envs)
        self.command[:] = scaled_rows(a)  # the single env's feed scale, bit for bit
        st, running = self.state, self.active.copy()
        self._draw_ahead(running)
        t0 = time.perf_counter()
        if self.threads > 1:
            numba.set_num_threads(self.threads)  # this thread's setting, for its next parallel call
            sk.advance_batch_threaded(
                *self.arrays, self.command, self.normals.rows, self.record, self.recorded, running
            )
        else:
            sk.advance_batch(*self.arrays, self.command, self.normals.rows, self.record, self.recorded, running)
        self.kernel_s += time.perf_counter() - t0
        if st["singular"].any():
            i = int(np.argmax(st["singular"]))
            raise np.linalg.LinAlgError(f"episode {i}: singular TCP Jacobian at q = {st['q_motor_rad'][i]}")
        rows, reward = np.empty((4, self.num_envs)), np.empty(self.num_envs)
        batch_rewards_into(
            self._weights, st["step_deviation_m"], st["step_lateral_n"], a, self.prev_action, self.peak_lateral_n,
            running, rows, reward,
        )  # fmt: skip
        terms = dict(zip(TERM_NAMES, rows, strict=True))
        self.prev_action = a
        terminated = st["terminated"] & running
        truncated = st["truncated"] & running
        if self.max_episode_steps < MAX_EPISODE_STEPS:
            truncated |= running & ~terminated & (st["steps"] >= self.max_episode_steps)
            st["truncated"][truncated] = True
        infos: dict[str, Any] = {
            "t_s": st["t_s"].copy(),
            "phase": st["phase"].copy(),
            "deviation_m": np.hypot(st["sample"][:, 0], st["sample"][:, 1]),
            "reward_terms": terms,
        }
        obs = self._observation()
        ended = (terminated | truncated).nonzero()[0]
        if ended.size:
            final_info: dict[str, Any] = {}
            for i in ended.tolist():
                final_info = self._add_info(final_info, self.final_info(i), i)
            infos["final_obs"] = {k: v.copy() for k, v in obs.items()}
            infos["_final_obs"] = terminated | truncated
            infos["final_info"] = final_info
            infos["_final_info"] = terminated | truncated
            for i in ended.tolist():  # each generator where the single env's step-by-step draws leave it
                self.normals.sync(i, self.envs[i].np_random, st["noise_at"])
            if not self.autoreset:
                self.active[ended] = False
                return obs, reward, terminated, truncated, infos
            for i in ended.tolist():
                self._reset_one(i, None)
            fresh = self._observation()
            for k in obs:
                obs[k][ended] = fresh[k][ended]
        return obs, reward, terminated, truncated, infos

    def close(self, **kwargs: Any) -> None:
        """Close every episode's env."""
        for e in self.envs:
            e.close()

    # ------------------------------------------------------------------ helpers
    def _observation(self) -> dict[str, np.ndarray]:
        """The single env's observation (:meth:`UR5BoneDrillEnv._observation`) of every episode, batched."""
        return observation_from_state(self.state, self.params, self.recorded > 0, self.scenario.tracker, self.num_envs)

    def final_info(self, i: int) -> dict[str, Any]:
        """Episode ``i``'s last info: the single env's privileged entries and its metrics."""
        return {
            **privileged_info(self.state, i),
            "specimen_hardness": float(self.params[i]["force_scale"]),
            "metrics": self.episode_metrics(i),
            "metrics_truncated": bool(self.state[i]["truncated"]),
        }

    def last_step_channels(self, i: int) -> dict[str, np.ndarray]:
        """Episode ``i``'s recorded channels of its last step (five rows, one per F/T sample)."""
        k = int(self.recorded[i])
        return record_channels(self.record[i, k - SUBSTEPS_PER_STEP : k])

    def records(self, i: int) -> SimpleNamespace:
        """Episode ``i``'s recorded channels so far: the recorder's (arrays, one row per F/T sample)."""
        return SimpleNamespace(**record_channels(self.record[i, : self.recorded[i]]))

    def episode_metrics(self, i: int) -> dict[str, float]:
        """Episode ``i``'s metrics so far (:func:`drillgym.envs.metrics.episode_metrics`)."""
        sc = self.scenario_of(i)
        centre = centre_at(self.arrays.centre[i], self.arrays.bins[i], float(self.params[i]["bin_m"]), sc.entry_depth_m)
        offset = math.hypot(centre[0], centre[1]) if centre is not None else math.nan
        return episode_metrics(self.records(i), sc.entry_depth_m, sc.depth_m, offset, feed_phase=int(Phase.FEED))


def _check_compiled(spec: str) -> None:
    """``UserError`` unless every effect of ``spec`` runs in the compiled step (a bad spec raises its own)."""
    if not runs_compiled(spec):
        raise UserError(f"effects {spec!r} do not all run in the compiled step; use UR5BoneDrillEnv")


def _record_rows(max_time_s: float) -> int:
    """Sample rows an episode of ``max_time_s`` can record (its steps, at most the step limit, two spare)."""
    return min(MAX_EPISODE_STEPS, math.ceil(max_time_s / CONTROL_DT_S) + 2) * SUBSTEPS_PER_STEP


def _grown(old: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``old`` if each episode's row holds ``shape``, else a zero-padded copy that does, contents kept."""
    if all(m <= k for m, k in zip(shape, old.shape[1:], strict=True)):
        return old
    new = np.zeros((old.shape[0], *(max(m, k) for m, k in zip(shape, old.shape[1:], strict=True))), old.dtype)
    new[tuple(slice(0, k) for k in old.shape)] = old
    return new
