"""Which holes would tell two explanations apart: each one plays the reality, the other is judged on its logs.

A diagnosis can name a model while another, with other physics, is not ruled out by the held-out episodes
(``alternatives`` in ``diagnosis.json``): a thermal softening and a density gradient both scale the forces as the
hole deepens, and with a dozen holes the data may not prefer either. The way to separate them is to drill where
their predictions part. For each change of a grid (a feed rate as a factor of each hole's own, or an interaction
angle), a few of the logged holes (scenario and controller) are simulated again with that change and one model's
effects on, at its fitted values, and logged as the real cell would log them (noise, a drawn specimen); the other
model is replayed on those logs and scored with the diagnosis's own gap (:mod:`drillgym.eval.diagnosis.gap`). Its
gap over the true model's own, the **separation**, says how far apart the two are there: about 1 where the data
could not tell them apart, and the larger, the fewer holes it takes. Both directions are run (each model playing the
reality), and a change counts by the smaller of the two.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS
from drillgym.envs.errors import UserError
from drillgym.envs.scenario import RANGES
from drillgym.eval.diagnosis.context import DiagnosisData, Evaluator, Spec, baseline_job, build, make_spec
from drillgym.eval.diagnosis.episodes import EpisodeData, load_episodes
from drillgym.eval.diagnosis.gap import pooled
from drillgym.eval.diagnosis.rank import other_physics
from drillgym.eval.diagnosis.reality.generate import log_episodes
from drillgym.eval.diagnosis.replay import Replayer
from drillgym.eval.diagnosis.where import gap_significance
from drillgym.eval.pool import WorkerPool

FEED_FACTORS = (0.25, 0.5, 1.0, 2.0)
"""Feeds tried, as factors of each logged hole's own feed (1.0: the holes as logged)."""
BETAS_DEG = (0.0, 40.0)
"""Interaction angles tried (deg), each for every hole at its logged feed: a perpendicular entry and the steepest
the simulator takes."""
HOLES = 3
"""Logged holes re-simulated per feed and direction (one per controller first)."""


@dataclass(frozen=True)
class Model:
    """A fitted model of a diagnosis: its name (``a+b``), effects and parameters (SI)."""

    name: str
    spec: Spec


def models_to_separate(diagnosis: dict[str, Any]) -> tuple[Model, list[Model]]:
    """The named model and the alternatives with other physics that the held-out data did not rule out.

    Raises:
        UserError: the diagnosis named nothing, or left no alternative with other physics to separate.
    """
    try:
        entries = {e["name"]: e for e in diagnosis.get("effects", [])}
        named = next((e for e in entries.values() if e.get("named")), None)
        if named is None:
            raise UserError(f"the diagnosis named no model (verdict {diagnosis.get('verdict')!r}): nothing to separate")
        first = _model(named)
        alts = other_physics(named["effects"], diagnosis.get("alternatives") or [])
        others = [_model(entries[a["name"]]) for a in alts if a["name"] in entries]
    except (KeyError, TypeError, AttributeError) as e:
        raise UserError(f"not a diagnosis.json that drillgym diagnose wrote: {type(e).__name__} {e}") from e
    if not others:
        raise UserError(
            f"the diagnosis named {first.name} and ruled out every model with other physics: nothing to separate"
        )
    return first, others


def _model(entry: dict[str, Any]) -> Model:
    names = list(entry["effects"])
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise UserError(f"diagnosis model {entry['name']!r} has effects this version does not know: {unknown}")
    return Model(entry["name"], make_spec(names, [entry["params"][n] for n in names]))


def pick_holes(episodes: Sequence[EpisodeData], holes: int = HOLES) -> list[EpisodeData]:
    """``holes`` logged episodes, one per controller in turn (so every controller is represented)."""
    by_controller: dict[str, list[EpisodeData]] = {}
    for ep in episodes:
        by_controller.setdefault(ep.controller, []).append(ep)
    out: list[EpisodeData] = []
    queues = [list(v) for _, v in sorted(by_controller.items())]
    while len(out) < holes and any(queues):
        for q in queues:
            if q and len(out) < holes:
                out.append(q.pop(0))
    return out


@dataclass(frozen=True)
class Change:
    """A change of the logged holes' scenarios.

    ``knob`` ``"feed"``: ``value`` is a factor of each hole's feed; ``"beta"``: the interaction angle of every hole (deg).
    """

    knob: str
    value: float

    def scenario(self, logged: dict[str, Any]) -> dict[str, Any]:
        """A hole's scenario with this change."""
        if self.knob == "feed":
            return dict(logged, feed_mm_s=self.value * float(logged["feed_mm_s"]))
        return dict(logged, beta_deg=self.value)

    @property
    def as_logged(self) -> bool:
        """The holes as they were logged (a feed factor of 1)."""
        return self.knob == "feed" and self.value == 1.0

    def label(self, short: bool = False) -> str:
        """Words for the report: ``0.25 x the logged feed``, ``an interaction angle of 0 deg``.

        ``short``: ``0.25x feed``, ``0 deg`` (a figure's ticks).
        """
        if self.knob == "feed":
            return f"{self.value:g}x feed" if short else f"{self.value:g} x the logged feed"
        return f"{self.value:g} deg" if short else f"an interaction angle of {self.value:g} deg"


def changes(factors: Sequence[float] = FEED_FACTORS, betas_deg: Sequence[float] = BETAS_DEG) -> list[Change]:
    """The feed factors, then the angles, as :class:`Change` s."""
    return [Change("feed", float(f)) for f in factors] + [Change("beta", float(b)) for b in betas_deg]


def check_changes(grid: Sequence[Change], holes: Sequence[EpisodeData]) -> None:
    """Every changed hole must be a scenario the simulator takes (``UserError`` otherwise)."""
    for c in grid:
        if not np.isfinite(c.value) or (c.knob == "feed" and c.value <= 0):
            raise UserError(f"{c.knob} {c.value}: a feed factor must be a positive number, an angle a finite one")
        key = "feed_mm_s" if c.knob == "feed" else "beta_deg"
        low, high, inclusive_low = RANGES[key]
        for ep in holes:
            v = float(c.scenario(ep.scenario)[key])
            if not ((low <= v) if inclusive_low else (low < v)) or v > high:
                raise UserError(
                    f"{c.label()} gives {key} = {v:.3g} for {ep.name} (logged {ep.scenario[key]}); "
                    f"the simulator takes {'[' if inclusive_low else '('}{low}, {high}]"
                )


def separation_at(
    truth: Model, other: Model, holes: Sequence[EpisodeData], change: Change, seed: int, replayer: Replayer
) -> dict[str, Any]:
    """``other``'s gap on holes simulated with ``truth`` on and ``change`` made, over ``truth``'s own gap.

    Returns ``{"knob", "value", "feeds_mm_s", "betas_deg", "truth", "other", "separation", "significant",
    "truth_ratio"}``: ``separation`` is ``other``'s pooled gap over ``truth``'s; ``significant`` whether ``other``'s
    excess over it is beyond the holes' scatter (:func:`~drillgym.eval.diagnosis.where.gap_significance`,
    ``truth``'s terms as the null); ``truth_ratio``: ``truth``'s own gap over the simulator's own level (≈ 1).
    """
    rng = np.random.default_rng(seed)
    scenarios = [change.scenario(ep.scenario) for ep in holes]
    plans = [
        {"scenario": sc, "controller": ep.controller, "seed": int(rng.integers(2**31 - 1))}
        for sc, ep in zip(scenarios, holes, strict=True)
    ]
    with tempfile.TemporaryDirectory(prefix="drillgym-separate-") as tmp:
        log_episodes(plans, lambda i: build(truth.spec), Path(tmp))
        episodes, _ = load_episodes(Path(tmp), strict=True)
    idx = list(range(len(episodes)))
    data = DiagnosisData.from_episodes(episodes, idx, idx)
    data.add_baseline([baseline_job(replayer, ep) for ep in episodes])
    ev = Evaluator(data, replayer)
    t_truth, t_other = ev.terms(truth.spec, idx), ev.terms(other.spec, idx)
    g_truth, g_other, g_null = pooled(t_truth), pooled(t_other), pooled(data.null_terms)
    return {
        "knob": change.knob,
        "value": change.value,
        "feeds_mm_s": [float(sc["feed_mm_s"]) for sc in scenarios],
        "betas_deg": [float(sc["beta_deg"]) for sc in scenarios],
        "truth": truth.name,
        "other": other.name,
        "separation": float(g_other / g_truth),
        "significant": bool(gap_significance(t_other, t_truth, seed=seed)["significant"]),
        "truth_ratio": float(g_truth / g_null),
    }


_REPLAYER: Replayer | None = None
"""This process's replayer (its env is built once and kept between jobs)."""


def _separation_job(job: tuple[Model, Model, Sequence[EpisodeData], Change, int]) -> dict[str, Any]:
    """:func:`separation_at` for one ``(truth, other, holes, change, seed)``, on this process's replayer."""
    global _REPLAYER
    if _REPLAYER is None:
        _REPLAYER = Replayer()
    truth, other, holes, change, seed = job
    return separation_at(truth, other, holes, change, seed, _REPLAYER)


def separate(
    diagnosis: dict[str, Any],
    episodes: Sequence[EpisodeData],
    grid: Sequence[Change] | None = None,
    holes: int = HOLES,
    seed: int = 0,
    progress: Callable[[int], None] | None = None,
    workers: int = 1,
) -> dict[str, Any]:
    """For the named model against each alternative with other physics: the separation at each change, both ways.

    ``grid``: the changes tried (default :func:`changes`: :data:`FEED_FACTORS` and :data:`BETAS_DEG`). ``workers``:
    processes (this one and ``workers - 1`` spawned ones, :class:`~drillgym.eval.pool.WorkerPool`); each change and
    direction is one job, seeded on its own, so the rows do not depend on how many there are. ``progress(jobs)`` is
    called as each job ends, with the number of jobs. Every argument is checked before any hole is simulated.

    Returns ``{"named", "holes", "changes", "pairs": [{"other", "rows", "weakest", "best"}]}``: ``rows`` per change
    and direction (:func:`separation_at`); ``weakest``: per change (``knob``, ``value``), the smaller separation of
    the two directions; ``best``: the ``weakest`` entry with the largest separation, where to drill to tell them apart.
    """
    grid = changes() if grid is None else list(grid)
    named, others = models_to_separate(diagnosis)
    chosen = pick_holes(episodes, holes)
    if not chosen:
        raise UserError("no logged episode to take the holes' scenarios from")
    if not grid:
        raise UserError("no change to try: the feed factors and the angles are both empty")
    check_changes(grid, chosen)
    jobs = [
        (truth, judged, chosen, change, seed + 1000 * k + j)
        for k, other in enumerate(others)
        for j, change in enumerate(grid)
        for truth, judged in ((named, other), (other, named))
    ]
    done: dict[int, dict[str, Any]] = {}
    with WorkerPool(max(1, min(workers, len(jobs))), here=True) as pool:
        for i, row in pool.map_unordered(_separation_job, jobs):
            done[i] = row
            if progress is not None:
                progress(len(jobs))
    per_pair = 2 * len(grid)
    pairs = []
    for k, other in enumerate(others):
        rows = [done[i] for i in range(k * per_pair, (k + 1) * per_pair)]
        weakest = [  # the jobs' order: each change, the named model true, then the other
            {"knob": c.knob, "value": c.value, "separation": min(a["separation"], b["separation"])}
            for c, a, b in zip(grid, rows[0::2], rows[1::2], strict=True)
        ]
        best = max(weakest, key=lambda w: w["separation"])
        pairs.append({"other": other.name, "rows": rows, "weakest": weakest, "best": best})
    return {
        "named": named.name,
        "holes": [ep.name for ep in chosen],
        "changes": [{"knob": c.knob, "value": c.value} for c in grid],
        "pairs": pairs,
    }
