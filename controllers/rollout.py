"""The rollout loops: run episodes with any policy that follows SB3's ``predict`` protocol.

Classical, residual and learned controllers alike. :func:`run_episode` runs one episode on any env (the
simulated cell with any effect, the real cell); :func:`run_episodes` runs a set of seeded episodes of one
simulated scenario at once on the batched engine (:class:`drillgym.envs.batched.BatchedDrillEnv`), one policy
copy per episode, with the results :func:`run_episode` gives on the single env, bit for bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Protocol

import gymnasium as gym
import numpy as np

from drillgym import envs  # noqa: F401  (registers the ids)
from drillgym.controllers.base import stack_controllers
from drillgym.controllers.closed_loop import run_closed_loop
from drillgym.controllers.step_log import StepLog
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.errors import UserError
from drillgym.envs.plan import DrillPlan


class PolicyPredictor(Protocol):
    """SB3's predictor protocol: what ``evaluate_policy`` and our benchmarks call."""

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, Any]:
        """Action for ``observation`` (and the recurrent state, unused by stateless policies)."""
        ...


@dataclass
class EpisodeResult:
    """Metrics and per-F/T-sample traces of one episode.

    Attributes:
        seed: the reset seed (None: the env's wrapper chose it).
        metrics: :data:`drillgym.envs.metrics.METRIC_NAMES`.
        trace: per-F/T-sample traces (empty without ``keep_trace``).
        steps: agent steps taken.
        sim_time_s: env time at the end (s).
        failure: ``""``, the env's failure (e.g. ``"force_limit"``) or ``"truncated"``.
        info: the last step's ``info`` (a real cell's ``error``, stop result, ...).
        rewards: the env's reward of each step.
    """

    seed: int | None
    metrics: dict[str, float]
    trace: dict[str, np.ndarray]
    steps: int = 0
    sim_time_s: float = math.nan
    failure: str = ""
    info: dict[str, Any] = field(default_factory=dict)
    rewards: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def row(self) -> dict[str, Any]:
        """The metrics plus ``steps``, ``sim_time_s`` and ``failure``: one row of a benchmark table."""
        return {**self.metrics, "steps": self.steps, "sim_time_s": self.sim_time_s, "failure": self.failure}


def run_episode(
    env: gym.Env,
    policy: PolicyPredictor | None = None,
    seed: int | None = 0,
    keep_trace: bool = True,
    options: dict[str, Any] | None = None,
) -> EpisodeResult:
    """Reset with ``seed`` (and ``options``) and run to the end; ``policy=None`` commands zero correction, nominal feed.

    A policy with a ``set_plan`` method (every :class:`drillgym.controllers.Controller`) is handed the
    episode's plan after the reset, as the benchmark does. ``seed=None`` leaves the seed to the env (a
    wrapper such as ``ScenarioCycle`` sets its own).
    """
    obs, _ = env.reset(seed=seed, options=options)
    if policy is not None and hasattr(policy, "set_plan"):
        policy.set_plan(env.unwrapped.plan)  # type: ignore[attr-defined]
    state, start, steps = None, True, 0
    rewards: list[float] = []
    zero = np.zeros(ACTION_DIM, dtype=np.float32)
    while True:
        if policy is None:
            action = zero
        else:
            action, state = policy.predict(obs, state=state, episode_start=np.array([start]), deterministic=True)
        obs, reward, terminated, truncated, info = env.step(action)
        rewards.append(float(reward))
        start, steps = False, steps + 1
        if terminated or truncated:
            break
    metrics = info.get("metrics") or env.unwrapped.episode_metrics()  # type: ignore[attr-defined]
    failure = info.get("failure") or ("truncated" if truncated and not terminated else "")
    trace: dict[str, np.ndarray] = {}
    if keep_trace:
        rec = env.unwrapped.recorder  # type: ignore[attr-defined]
        trace = {
            "t_s": np.asarray(rec.t_s),
            "phase": np.asarray(rec.phase),
            "stage": np.asarray(rec.stage),
            "depth_cmd_m": np.asarray(rec.depth_cmd_m),
            "deviation_m": np.asarray(rec.deviation_m),
            "ft_force_n": np.asarray(rec.ft_force_n),
        }
    t_s = float(info.get("t_s", math.nan))
    return EpisodeResult(seed, dict(metrics), trace, steps, t_s, str(failure), dict(info), np.asarray(rewards))


StepHook = Callable[[BatchedDrillEnv, int, np.ndarray, dict[str, np.ndarray], list[int], np.ndarray], None]
"""``on_step(batch, step, actions, obs, running, ended)`` of :func:`run_episodes`: after agent step ``step`` (0 first) of
the episodes in ``running`` (slot indices), with the actions sent (N, 4), the observation after it (ended episodes'
last) and which episodes ended at it (N, bool)."""


def same_plan(a: DrillPlan, b: DrillPlan) -> bool:
    """Whether two plans are the same hole and tool (every field equal)."""
    return all(
        np.array_equal(getattr(a, f.name), getattr(b, f.name))
        if f.name == "T_base_task"
        else getattr(a, f.name) == getattr(b, f.name)
        for f in fields(a)
    )


def run_episodes(
    make_policy: Callable[[], PolicyPredictor],
    seeds: Sequence[int],
    env_kwargs: dict[str, Any] | None = None,
    effects: str | Sequence[str] = "",
    on_step: StepHook | None = None,
    log: Callable[[BatchedDrillEnv], StepLog] | None = None,
    compiled: bool = True,
) -> list[EpisodeResult]:
    """Run one episode per seed of a simulated scenario on the batched engine, each with its own policy.

    Args:
        make_policy: builds one policy (a :class:`drillgym.controllers.Controller`, a trained model...); each
            episode gets its own copy, handed its episode's plan (``set_plan``) as :func:`run_episode` does, except
            a :attr:`~drillgym.controllers.Controller.batchable` controller: one copy steps every episode
            (:meth:`~drillgym.controllers.Controller.act_batch`), with the same actions.
        seeds: the episodes' reset seeds, one batch slot each.
        env_kwargs: the single env's arguments (scenario, cell parameters).
        effects: an effect spec of compiled effects (:class:`~drillgym.envs.batched.BatchedDrillEnv`), or one per
            seed (a cell drawn per episode).
        on_step: called after every step (:data:`StepHook`; the steps then run in Python).
        log: makes the episodes' logs once the batch is reset (:class:`~drillgym.controllers.step_log.StepLog`,
            e.g. :class:`drillgym.eval.logs.batch_logger.BatchLogger`), kept as the episodes run (in compiled code
            too, :func:`run_batch`).
        compiled: let the li2023 family run in compiled code (:func:`run_batch`); False: the Python loop.

    Returns:
        One :class:`EpisodeResult` per seed, in order, equal to :func:`run_episode` on the single env with
        ``keep_trace=False`` (its ``info`` is the batched env's final info of the episode).
    """
    per_episode = [effects] * len(seeds) if isinstance(effects, str) else list(effects)
    batch = BatchedDrillEnv(len(seeds), autoreset=False, **(env_kwargs or {}))
    try:
        return run_batch(batch, make_policy, seeds, on_step=on_step, effects=per_episode, log=log, compiled=compiled)
    finally:
        batch.close()


def run_batch(
    batch: BatchedDrillEnv,
    policies: Callable[[], PolicyPredictor] | Sequence[PolicyPredictor],
    seeds: Sequence[int],
    scenarios: Sequence[dict[str, Any] | None] | None = None,
    on_step: StepHook | None = None,
    started: dict[str, np.ndarray] | None = None,
    effects: Sequence[str] | None = None,
    compiled: bool = True,
    log: Callable[[BatchedDrillEnv], StepLog] | None = None,
) -> list[EpisodeResult]:
    """Run one episode in each slot of ``batch`` (built with ``autoreset=False``) to its end.

    ``policies``: a factory as :func:`run_episodes` takes, or one policy per slot (each handed its slot's plan);
    ``scenarios``: each slot's scenario changes for this reset (kept for its next ones, as the single env keeps
    them), None for the scenario the slot has; ``effects``: each slot's effect spec for this reset (kept likewise);
    ``started``: the observation of a reset the caller has just made with these seeds, scenarios and effects (the
    episodes start from it, without another reset); ``compiled``: where one stacked ``li2023``-family controller
    drives every slot, without ``on_step``, run the steps in compiled code
    (:mod:`drillgym.controllers.closed_loop`: the same numbers; False steps in Python); ``log``: makes the episodes'
    logs (:class:`~drillgym.controllers.step_log.StepLog`) once the batch is reset, kept step by step. The rest as
    :func:`run_episodes`.
    """
    n = batch.num_envs
    if len(seeds) != n:
        raise UserError(f"{len(seeds)} seeds for a batch of {n} episodes")
    if started is None:
        options: dict[str, Any] = {}
        if scenarios is not None:
            options["scenario"] = list(scenarios)
        if effects is not None:
            options["effects"] = list(effects)
        obs, _ = batch.reset(seed=[int(s) for s in seeds], options=options or None)
    else:
        obs = started
    slots, batched, alone = _stepping(policies, [env.plan for env in batch.envs])
    results: list[EpisodeResult | None] = [None] * n

    def end(i: int, own: np.ndarray) -> None:
        """Slot ``i`` has ended (it stays as it ended: autoreset off) with these rewards: its result."""
        info = batch.final_info(i)
        ended_by = info["failure"] or (
            "truncated" if info["metrics_truncated"] and not batch.state[i]["terminated"] else ""
        )
        results[i] = EpisodeResult(
            int(seeds[i]), {k: float(v) for k, v in info["metrics"].items()}, {}, len(own), float(info["t_s"]),
            str(ended_by), info, own,
        )  # fmt: skip

    logs = None if log is None else log(batch)
    hook = on_step if logs is None else _logging(logs, on_step)
    whole = len(batched) == 1 and not alone and len(batched[0][0]) == n
    if not (compiled and on_step is None and whole and run_closed_loop(batch, batched[0][1], end, logs)):
        _run_python(batch, slots, batched, alone, obs, end, hook)
    assert all(r is not None for r in results)
    return results  # type: ignore[return-value]


def _logging(logs: StepLog, on_step: StepHook | None) -> StepHook:
    """A step hook keeping each step in ``logs``, then calling ``on_step`` (if any)."""

    def hook(
        batch: BatchedDrillEnv, step: int, actions: np.ndarray, obs: dict[str, np.ndarray], running: list[int],
        ended: np.ndarray,
    ) -> None:  # fmt: skip
        logs.log_step(step, actions, obs, running, ended)
        if on_step is not None:
            on_step(batch, step, actions, obs, running, ended)

    return hook


def _run_python(
    batch: BatchedDrillEnv,
    slots: list[Any],
    batched: list[tuple[np.ndarray, Any]],
    alone: list[int],
    obs: dict[str, np.ndarray],
    end: Callable[[int, np.ndarray], None],
    on_step: StepHook | None,
) -> None:
    """:func:`run_batch`'s loop in Python, a step at a time: each step's actions, then the batch's step."""
    n = batch.num_envs
    states: list[Any] = [None] * n
    start = np.ones(n, dtype=bool)
    rewards: list[np.ndarray] = []  # each step's rewards of every slot (0 for the slots not running)
    actions = np.zeros((n, ACTION_DIM), dtype=np.float32)
    step = 0
    while batch.active.any():
        running_mask = batch.active.copy()
        running = running_mask.nonzero()[0].tolist()
        for idx, policy in batched:  # the ended episodes' rows too (their last observation): not sent, not stepped
            actions[idx] = policy.act_batch(obs if len(idx) == n else {k: v[idx] for k, v in obs.items()})
        for i in (i for i in alone if batch.active[i]):
            one = {k: v[i] for k, v in obs.items()}
            actions[i], states[i] = slots[i].predict(
                one, state=states[i], episode_start=np.array([start[i]]), deterministic=True
            )
        obs, reward, terminated, truncated, _ = batch.step(actions)
        ended = terminated | truncated
        if on_step is not None:
            on_step(batch, step, actions, obs, running, ended)
        step += 1
        rewards.append(reward)
        start[running_mask] = False
        for i in (ended & running_mask).nonzero()[0].tolist():
            end(i, np.array([row[i] for row in rewards]))  # every slot started at the first step


def _stepping(
    policies: Callable[[], PolicyPredictor] | Sequence[PolicyPredictor], plans: list[DrillPlan]
) -> tuple[list[Any], list[tuple[np.ndarray, Any]], list[int]]:
    """Each slot's policy, handed its plan; the groups stepped as one batch ``(rows, controller)``; the slots alone.

    A factory's batchable controller with one plan for every slot is one copy over all rows; otherwise each slot has
    its own policy, and controllers that stack (:func:`~drillgym.controllers.base.stack_controllers`) step together.
    """
    n = len(plans)
    if callable(policies):
        first = policies()
        if n > 1 and getattr(first, "batchable", False) and all(same_plan(p, plans[0]) for p in plans):
            first.set_plan(plans[0], n)  # type: ignore[attr-defined]
            return [first], [(np.arange(n), first)], []
        slots = [first] + [policies() for _ in range(n - 1)]
    else:
        slots = list(policies)
        if len(slots) != n:
            raise UserError(f"{len(slots)} policies for a batch of {n} episodes")
    for policy, plan in zip(slots, plans, strict=True):
        if hasattr(policy, "set_plan"):
            policy.set_plan(plan)
    groups = stack_controllers(slots)
    return slots, [(np.asarray(idx), c) for idx, c in groups if len(idx) > 1], [i[0] for i, _ in groups if len(i) == 1]
