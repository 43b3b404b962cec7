"""Domain randomisation: a new scenario for every episode, drawn inside the training ranges.

Ranges (user units) live in :data:`DR_RANGES`; they are disjoint from the ``heldout`` suite's
conditions (:mod:`drillgym.eval.bench.suites` checks it), which is what makes that suite a test of generalisation.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers.residual import plan_support
from drillgym.envs.errors import UserError
from drillgym.envs.scenario import Scenario
from drillgym.envs.seeds import Purpose, draw_seed, in_namespace, training_stream

TRAINING_RANGES: dict[str, tuple[float, float]] = {
    "beta_deg": (15.0, 35.0),
    "feed_mm_s": (0.3, 1.0),
    "stickout_mm": (30.0, 42.0),
    "cortical_thickness_mm": (3.0, 10.0),
}
"""Numeric scenario parameters a residual policy is trained on: name -> (low, high), inclusive, user units."""
TRAINING_BONES: tuple[str, ...] = ("buffalo_femur", "bovine_tibia", "porcine_femur")
"""Bone presets a residual policy is trained on."""

DR_RANGES: dict[str, tuple[float, float]] = {
    **TRAINING_RANGES,
    "ft_noise_n": (0.0, 0.05),
    "latency_s": (0.005, 0.05),
    "tracker_noise_mm": (0.02, 0.1),
}
"""Uniform ranges per scenario argument (β in deg, feed in mm/s, stick-out and cortex in mm, noise, latency)."""


def check_ranges(ranges: dict[str, Any]) -> None:
    """Raise ``ValueError`` unless every entry is a numeric scenario argument with ``[low, high]`` inside its limits."""
    defaults = Scenario()
    for name, bounds in ranges.items():
        default = getattr(defaults, name, None)
        if isinstance(default, bool) or not isinstance(default, int | float):
            raise UserError(f"dr_ranges: {name!r} is not a numeric scenario argument")
        try:
            lo, hi = (float(v) for v in bounds)
        except (TypeError, ValueError):
            raise UserError(f"dr_ranges: {name}={bounds!r} must be [low, high]") from None
        if not lo <= hi:
            raise UserError(f"dr_ranges: {name}=[{lo}, {hi}] needs low <= high")
        Scenario.from_kwargs(**{name: lo})  # the scenario's own range check, with its message
        Scenario.from_kwargs(**{name: hi})


def merged_ranges(extra: dict[str, Any] | None = None) -> dict[str, tuple[float, float]]:
    """:data:`DR_RANGES` with ``extra`` entries added or replacing theirs."""
    out = dict(DR_RANGES)
    for name, (lo, hi) in (extra or {}).items():
        out[name] = (float(lo), float(hi))
    return out


def training_plan_support(extra: dict[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The plan features a policy trained on :func:`merged_ranges` ``(extra)`` and :data:`TRAINING_BONES` has seen.

    (:func:`drillgym.controllers.residual.plan_support` of them: a policy's plan is clamped to it.)
    """
    return plan_support(merged_ranges(extra), TRAINING_BONES)


def sample_scenario(rng: np.random.Generator, ranges: dict[str, tuple[float, float]] = DR_RANGES) -> dict[str, Any]:
    """One scenario: every ranged argument uniform, the bone one of the training presets.

    β is rounded to 0.5° (the force tables are cached per β) and its sign kept positive.
    """
    out: dict[str, Any] = {k: float(rng.uniform(lo, hi)) for k, (lo, hi) in ranges.items()}
    if "beta_deg" in out:
        out["beta_deg"] = round(out["beta_deg"] * 2.0) / 2.0
    out["bone"] = str(rng.choice(list(TRAINING_BONES)))
    return out


class DomainRandomization(gym.Wrapper):
    """At every reset, draw a scenario from the wrapper's own generator and pass it to the env.

    With ``paper_share`` > 0 that share of the episodes is drilled in the env's own scenario (the one it was
    made with: the paper scenario for a default env) instead of a draw; 0 draws every episode, as before.

    The draws come from a generator seeded by the first ``reset(seed=...)`` (and ``stream_keys``: a run's seed
    and a worker's rank; :func:`drillgym.envs.seeds.training_stream`), so a seeded training run
    sees the same sequence of scenarios. The env's own seed stays in the training namespace
    (:mod:`drillgym.envs.seeds`): a given seed already there (a :class:`PairedReward` above) is passed on,
    any other is replaced by a draw there, so no training episode drills a judge episode's specimen.
    """

    def __init__(
        self,
        env: gym.Env,
        ranges: dict[str, tuple[float, float]] | None = None,
        paper_share: float = 0.0,
        stream_keys: tuple[int, ...] = (),
    ):
        super().__init__(env)
        self.stream_keys = tuple(int(k) for k in stream_keys)
        if not 0.0 <= paper_share <= 1.0:
            raise UserError(f"paper_share={paper_share!r} must be in [0, 1]")
        self.ranges = dict(DR_RANGES if ranges is None else ranges)
        self.paper_share = float(paper_share)
        self._paper = dict(env.unwrapped.scenario.to_dict())  # type: ignore[attr-defined]
        self._rng: np.random.Generator | None = None
        self.current: dict[str, Any] = {}

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Draw a scenario (or, with ``paper_share``, sometimes the env's own) and reset the env with it."""
        env_seed: int | None = None
        if seed is not None or self._rng is None:
            self._rng = training_stream(self.stream_keys, seed)
            in_training = seed is not None and in_namespace(seed, Purpose.TRAIN)
            env_seed = seed if in_training else draw_seed(self._rng, Purpose.TRAIN)
        if self.paper_share > 0.0 and self._rng.uniform() < self.paper_share:
            self.current = dict(self._paper)
        else:
            self.current = sample_scenario(self._rng, self.ranges)
        opts = {**(options or {}), "scenario": {**self.current, **(options or {}).get("scenario", {})}}
        obs, info = self.env.reset(seed=env_seed, options=opts)
        return obs, {**info, "scenario": dict(self.current)}


VALIDATION_SEED = 20_231
"""Seed of the validation scenarios' draw (fixed: every run selects its best model on the same set)."""


def validation_scenarios(
    n: int, seed: int = VALIDATION_SEED, ranges: dict[str, tuple[float, float]] = DR_RANGES
) -> list[dict[str, Any]]:
    """The paper scenario (env defaults) and ``n - 1`` fixed draws inside the training ranges.

    Used to pick a run's best model: held-in conditions, never the ``heldout`` suite's.
    """
    rng = np.random.default_rng(seed)
    return [{}] + [sample_scenario(rng, ranges) for _ in range(max(n - 1, 0))]


class ScenarioCycle(gym.Wrapper):
    """Reset into the next scenario of a fixed list, in turn: ``len(scenarios)`` episodes visit each once.

    With ``seeds`` (one per scenario) every visit of a scenario replays the same episode (noise and
    specimen draws), so successive evaluations differ only by the policy.
    """

    def __init__(self, env: gym.Env, scenarios: list[dict[str, Any]], seeds: list[int] | None = None):
        super().__init__(env)
        if not scenarios:
            raise UserError("ScenarioCycle needs at least one scenario")
        if seeds is not None and len(seeds) != len(scenarios):
            raise UserError(f"{len(seeds)} seeds for {len(scenarios)} scenarios")
        self.scenarios = [dict(s) for s in scenarios]
        self.seeds = None if seeds is None else [int(x) for x in seeds]
        self.episode = 0
        # a listed scenario changes the env's own scenario, not the previous episode's: {} is the env's own
        self._initial = dict(env.unwrapped.scenario.to_dict())  # type: ignore[attr-defined]

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Reset with the next scenario of the list (and its seed, if the cycle has seeds)."""
        k = self.episode % len(self.scenarios)
        scenario = self.scenarios[k]
        self.episode += 1
        if self.seeds is not None:
            seed = self.seeds[k]
        full = {**self._initial, **scenario}
        obs, info = self.env.reset(seed=seed, options={**(options or {}), "scenario": full})
        return obs, {**info, "scenario": dict(scenario)}
