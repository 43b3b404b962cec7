"""The cell a residual is trained for: unmodelled effects at fixed values, some drawn afresh every episode.

A policy tuned in the ideal cell need not transfer to a real one (joint friction, latency, a tool longer than
planned: :mod:`drillgym.envs.effects`). :class:`TrainingCell` puts such effects into training:

* ``spec``: the effects and their values (an effect spec, ``"joint_friction:coulomb_rad=4.2e-4+latency:..."``,
  or a named cell of :data:`drillgym.envs.effects.cells.CELLS`); evaluation and model selection run the cell
  at these values;
* ``ranges``: parameters (``"effect.param"``) drawn uniformly in ``[low, high]`` for every training episode
  (domain randomisation over the cell: a diagnosis's 95 % intervals, ``drillgym train --cell-from-diagnosis``).

The effects are built afresh for every episode (an effect keeps per-episode state), from the spec text.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np

from drillgym.envs.effects.cells import cell_effects_spec
from drillgym.envs.effects.registry import EFFECTS, build_effects, parse_effect_spec, runs_compiled
from drillgym.envs.errors import UserError
from drillgym.envs.seeds import training_stream

CELL_STREAM = 7_001
"""Extra key of the cell draws' generator: apart from the scenario and seed draws of the same run and worker."""


@dataclass(frozen=True)
class TrainingCell:
    """Effects at fixed values (``spec``) and the parameters drawn per training episode (``ranges``).

    Attributes:
        spec: an effect spec or a named cell ('' : the ideal cell).
        ranges: ``{"effect.param": (low, high)}``: each training episode draws the parameter uniformly there; the
            effect must be in ``spec`` (its value there is what evaluation uses).
    """

    spec: str = ""
    ranges: dict[str, tuple[float, float]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        values = self.values  # parses and checks the spec (cell_effects_spec builds its effects)
        for key, bounds in self.ranges.items():
            effect, _, param = key.partition(".")
            if effect not in values:
                raise UserError(f"cell range {key!r}: the effect {effect!r} is not in the cell's spec {self.spec!r}")
            known = {p.name: p for p in EFFECTS[effect].params}
            if param not in known:
                raise UserError(f"cell range {key!r}: {effect} has no parameter {param!r}; it has {sorted(known)}")
            lo, hi = (float(v) for v in bounds)
            p = known[param]
            if not (np.isfinite(lo) and np.isfinite(hi) and p.low <= lo <= hi <= p.high):
                raise UserError(
                    f"cell range {key!r}: [{lo:g}, {hi:g}] must be ordered and inside [{p.low:g}, {p.high:g}]"
                )

    @property
    def values(self) -> dict[str, dict[str, float]]:
        """``{effect: {param: value}}`` of the spec (a named cell's spec looked up)."""
        spec = self.nominal_spec()
        return {name: dict(v) for name, v in parse_effect_spec(spec)} if spec else {}

    @property
    def compiled(self) -> bool:
        """Whether the compiled step runs every effect of the cell (the batched engine takes it)."""
        return runs_compiled(self.nominal_spec())

    def nominal_spec(self) -> str:
        """The effect spec at the cell's own values (a named cell's spec)."""
        return cell_effects_spec(self.spec) if self.spec else ""

    @property
    def empty(self) -> bool:
        """Whether the cell is the ideal one (no effect)."""
        return not self.nominal_spec()

    def draw_spec(self, rng: np.random.Generator) -> str:
        """An effect spec with the ranged parameters drawn (uniformly, in the order of ``ranges``)."""
        values = self.values
        for key, (lo, hi) in self.ranges.items():
            effect, _, param = key.partition(".")
            values[effect][param] = float(rng.uniform(lo, hi))
        return spec_of(values)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (``spec``, ``ranges``)."""
        return {"spec": self.spec, "ranges": {k: [float(a), float(b)] for k, (a, b) in self.ranges.items()}}


def spec_of(values: dict[str, dict[str, float]]) -> str:
    """The effect spec of ``{effect: {param: value}}`` (values written in full: ``repr`` round-trips)."""
    return "+".join(
        name + (":" + ",".join(f"{k}={v!r}" for k, v in params.items()) if params else "")
        for name, params in values.items()
    )


def with_cell(env: gym.Env, cell: TrainingCell) -> gym.Env:
    """``env`` (a simulated env, wrapped or not) with the cell's effects at its own values from the next reset on."""
    if not cell.empty:
        env.unwrapped.set_effects(build_effects(cell.nominal_spec()))  # type: ignore[attr-defined]
    return env


class CellDraws(gym.Wrapper):
    """At every reset, draw the cell's ranged parameters and reset the env with those effects.

    The draws come from a generator keyed by the first ``reset(seed=...)`` and ``stream_keys`` (a run's seed and a
    worker's rank; :func:`drillgym.envs.seeds.training_stream`), apart from the scenario draws. ``info["cell"]``
    holds the episode's effect spec (a :class:`~drillgym.training.paired_reward.PairedReward` above runs the base
    in the same cell).
    """

    def __init__(self, env: gym.Env, cell: TrainingCell, stream_keys: tuple[int, ...] = ()) -> None:
        super().__init__(env)
        self.cell = cell
        self.stream_keys = (*tuple(int(k) for k in stream_keys), CELL_STREAM)
        self._rng: np.random.Generator | None = None
        self.current = cell.nominal_spec()

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict[str, Any]]:
        """Draw the episode's effects and reset with them (an ``options["effects"]`` given wins)."""
        if seed is not None or self._rng is None:
            self._rng = training_stream(self.stream_keys, seed)
        self.current = self.cell.draw_spec(self._rng)
        opts = {"effects": build_effects(self.current) if self.current else [], **(options or {})}
        obs, info = self.env.reset(seed=seed, options=opts)
        return obs, {**info, "cell": self.current}
