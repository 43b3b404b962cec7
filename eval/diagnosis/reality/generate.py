"""Reality generator: episodes of the simulator with effects switched on, logged as a real cell would.

Each episode draws a scenario from a spread (interaction angle, feed, depth) and takes the next of
the controllers (``none``, ``li2023``, ``zhang2005``), so calibration and held-out halves see the same
variety; the sensor noise and the specimen's hardness come from a per-episode seed. The logs carry
``source: "real"``, no ``sim_*`` columns, no seed, and the *nominal* scenario (the effects are not
in it): nothing the diagnosis could use that a real cell would not give it. What was switched on is
returned (and written by the CLI next to, not inside, the log folder).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.effects.registry import parse_effect_spec
from drillgym.envs.errors import UserError
from drillgym.eval.diagnosis.reality.base import RealityEffect
from drillgym.eval.diagnosis.reality.bone import ForceScaleReset
from drillgym.eval.diagnosis.reality.library import REALITY_EFFECTS, describe_parameters, switched_on, switches
from drillgym.eval.logs import EpisodeLogger, build_header

BETAS_DEG = (15.0, 20.0, 25.0, 30.0, 35.0)
FEEDS_MM_S = (0.4, 0.6, 0.8, 1.0)
DEPTHS_MM = (4.0, 5.0, 6.0)
CONTROLLERS = ("none", "li2023", "zhang2005")


def build_reality(spec: str) -> list[RealityEffect]:
    """Reality effects of a spec ``NAME[:P=V,...][+NAME...]`` (``""`` or ``"none"``: clean).

    Raises:
        ValueError: an unknown effect or parameter, a value out of range, or an effect whose values switch
            nothing on (every parameter of :func:`~drillgym.eval.diagnosis.reality.library.switches` at 0): the
            message lists the effect's parameters and an example.
    """
    if spec.strip() in ("", "none", "clean"):
        return []
    out: list[RealityEffect] = []
    for name, values in parse_effect_spec(spec):
        if name not in REALITY_EFFECTS:
            raise UserError(f"unknown reality effect {name!r}; choose from {sorted(REALITY_EFFECTS)}")
        try:
            effect = REALITY_EFFECTS[name](**values)
        except ValueError as e:
            raise UserError(f"{e}; {describe_parameters(name)}") from e
        if not switched_on(effect):
            on = ", ".join(switches(type(effect)))
            raise UserError(
                f"reality effect {name!r} switches nothing on with {spec!r}: set one of {on} away from 0; "
                f"{describe_parameters(name)}"
            )
        out.append(effect)
    return out


def episode_reality(spec: str, rng: np.random.Generator, index: int = 0, episodes: int = 1) -> list[RealityEffect]:
    """The reality's effects for one episode, ready for ``env.set_effects``; empty for a clean reality.

    Their per-episode draws come from ``rng``, their place in a series is ``index`` of ``episodes``, and the
    specimen's own hardness is put back at each step first (:class:`ForceScaleReset`, so the bone effects multiply it).
    """
    effects = build_reality(spec)
    for e in effects:
        e.seed(rng)
        e.set_series(index, episodes)
    return [ForceScaleReset(), *effects] if effects else []


def episode_name(index: int) -> str:
    """Name of episode ``index``'s log (its file stem, which the diagnosis reports episodes by)."""
    return f"episode_{index:03d}"


def episode_plan(index: int, rng: np.random.Generator) -> dict[str, Any]:
    """Scenario, controller and seed of episode ``index``."""
    return {
        "scenario": {
            "beta_deg": float(rng.choice(BETAS_DEG)),
            "feed_mm_s": float(rng.choice(FEEDS_MM_S)),
            "depth_mm": float(rng.choice(DEPTHS_MM)),
        },
        "controller": CONTROLLERS[index % len(CONTROLLERS)],
        "seed": int(rng.integers(2**31 - 1)),
    }


def log_episodes(
    plans: Sequence[dict[str, Any]],
    effects_for: Callable[[int], list[Any]],
    out: Path,
    overwrite: bool = False,
    after: Callable[[dict[str, Any], list[Any]], None] | None = None,
) -> None:
    """Run each plan (``scenario``, ``controller``, ``seed``) in the simulator and log it as a real cell would.

    ``effects_for(i)``: the effects switched on for episode ``i`` (reality effects, or candidate effects when a
    candidate model plays the reality); ``after(plan, effects)``: called once the episode is logged. Logs are
    ``out/episode_NNN.parquet`` (``source: "real"``, no seed in the header).
    """
    env = gym.make(SIM_ENV_ID)
    try:
        for i, plan in enumerate(plans):
            controller = make_controller(plan["controller"])
            effects = effects_for(i)
            env.unwrapped.set_effects(effects or None)  # type: ignore[attr-defined]
            env.reset(seed=plan["seed"], options={"scenario": plan["scenario"]})
            header = build_header(env, controller.describe(), seed=None, source="real")
            logger = EpisodeLogger(env, out / f"{episode_name(i)}.parquet", header, overwrite=overwrite)
            # no seed: the episode continues the stream seeded above; the header keeps seed null
            run_episode(logger, controller, seed=None, keep_trace=False)
            logger.close_log()
            if after is not None:
                after(plan, effects)
    finally:
        env.close()


def make_reality(spec: str, episodes: int, seed: int, out: str | Path, overwrite: bool = False) -> dict[str, Any]:
    """Write ``episodes`` real-schema logs ``out/episode_NNN.parquet`` of a reality with ``spec`` on.

    Returns:
        The truth: the spec, each effect's parameters and the episodes' scenarios/controllers.
    """
    if episodes < 1:
        raise UserError(f"episodes={episodes} must be >= 1")
    build_reality(spec)  # validate before creating or running anything
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    plans = [episode_plan(i, rng) for i in range(episodes)]

    def effects_for(i: int) -> list[Any]:
        return episode_reality(spec, np.random.default_rng([seed, i, 7]), i, episodes)

    def after(plan: dict[str, Any], effects: list[Any]) -> None:
        own = {e.explains: v for e in effects if e.explains and (v := e.episode_candidate_values()) is not None}
        if own:  # what an effect that differs per episode was in this one, in its candidate's terms
            plan["episode_values"] = own

    log_episodes(plans, effects_for, out, overwrite=overwrite, after=after)
    return {
        "spec": spec,
        "effects": [{"name": e.name, "explains": e.explains, "params": e.values} for e in build_reality(spec)],
        "episodes": plans,
        "seed": seed,
    }


def write_truth(truth: dict[str, Any], path: str | Path) -> Path:
    """Write the truth JSON."""
    p = Path(path)
    p.write_text(json.dumps(truth, indent=2))
    return p
