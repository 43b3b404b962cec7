"""Which holes would tell two explanations apart: each one plays the reality, the other is judged on its logs.

A diagnosis can name a model while another, with other physics, is not ruled out by the held-out episodes
(``alternatives`` in ``diagnosis.json``): a thermal softening and a density gradient both scale the forces as the
hole deepens, and with a dozen holes the data may not prefer either. The way to separate them is to drill where
their predictions part. For each feed rate of a grid, a few of the logged holes (scenario and controller) are
simulated again at that feed with one model's effects on, at its fitted values, and logged as the real cell would
log them (noise, a drawn specimen); the other model is replayed on those logs and scored with the diagnosis's own
gap (:mod:`drillgym.eval.diagnosis.gap`). Its gap over the true model's own, the **separation**, says how far apart
the two are at that feed: about 1 where the data could not tell them apart, and the larger, the fewer holes it takes.
Both directions are run (each model playing the reality), and a feed counts by the smaller of the two.
"""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from drillgym.envs.effects.registry import EFFECTS, physics_set
from drillgym.envs.errors import UserError
from drillgym.envs.scenario import RANGES
from drillgym.eval.diagnosis.context import DiagnosisData, Evaluator, Spec, baseline_job, build, make_spec
from drillgym.eval.diagnosis.episodes import EpisodeData, load_episodes
from drillgym.eval.diagnosis.gap import pooled
from drillgym.eval.diagnosis.reality.generate import log_episodes
from drillgym.eval.diagnosis.replay import Replayer
from drillgym.eval.diagnosis.where import gap_significance

FEED_FACTORS = (0.25, 0.5, 1.0, 2.0)
"""Feeds tried, as factors of each logged hole's own feed (1.0: the holes as logged)."""
HOLES = 3
"""Logged holes re-simulated per feed and direction (one per controller first)."""


@dataclass(frozen=True)
class Model:
    """A fitted model of a diagnosis: its name (``a+b``), effects and parameters (SI)."""

    name: str
    spec: Spec

    @property
    def physics(self) -> frozenset[str]:
        """The physics it names (:func:`~drillgym.envs.effects.registry.physics_of` of each effect)."""
        return physics_set(n for n, _ in self.spec)


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
        others = [_model(entries[a["name"]]) for a in diagnosis.get("alternatives") or [] if a["name"] in entries]
    except (KeyError, TypeError, AttributeError) as e:
        raise UserError(f"not a diagnosis.json that drillgym diagnose wrote: {type(e).__name__} {e}") from e
    others = [m for m in others if m.physics != first.physics]
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


def check_factors(factors: Sequence[float], holes: Sequence[EpisodeData]) -> None:
    """Every feed ``factor × logged feed`` must be a feed the simulator takes (``UserError`` otherwise)."""
    low, high, _ = RANGES["feed_mm_s"]
    for f in factors:
        if not np.isfinite(f) or f <= 0:
            raise UserError(f"feed factor {f} must be a positive number")
        for ep in holes:
            feed = f * float(ep.scenario["feed_mm_s"])
            if not low < feed <= high:
                raise UserError(
                    f"feed factor {f} gives {feed:.3g} mm/s for {ep.name} (logged at {ep.scenario['feed_mm_s']} mm/s); "
                    f"the simulator takes ({low}, {high}] mm/s"
                )


def separation_at(
    truth: Model, other: Model, holes: Sequence[EpisodeData], factor: float, seed: int, replayer: Replayer
) -> dict[str, Any]:
    """``other``'s gap on holes simulated with ``truth`` on at ``factor`` × their feed, over ``truth``'s own gap.

    Returns ``{"feed_factor", "feeds_mm_s", "truth", "other", "separation", "significant", "truth_ratio"}``:
    ``separation`` is ``other``'s pooled gap over ``truth``'s; ``significant`` whether ``other``'s excess over it is
    beyond the holes' scatter (:func:`~drillgym.eval.diagnosis.where.gap_significance`, ``truth``'s terms as the
    null); ``truth_ratio``: ``truth``'s own gap over the simulator's own level (≈ 1).
    """
    rng = np.random.default_rng(seed)
    feeds = [factor * float(ep.scenario["feed_mm_s"]) for ep in holes]
    plans = [
        {
            "scenario": dict(ep.scenario, feed_mm_s=feed),
            "controller": ep.controller,
            "seed": int(rng.integers(2**31 - 1)),
        }
        for ep, feed in zip(holes, feeds, strict=True)
    ]
    with tempfile.TemporaryDirectory(prefix="drillgym-separate-") as tmp:
        log_episodes(plans, lambda i, plan: build(truth.spec), Path(tmp))
        episodes, _ = load_episodes(Path(tmp), strict=True)
    idx = list(range(len(episodes)))
    data = DiagnosisData.from_episodes(episodes, idx, idx)
    data.add_baseline([baseline_job(replayer, ep) for ep in episodes])
    ev = Evaluator(data, replayer)
    t_truth, t_other = ev.terms(truth.spec, idx), ev.terms(other.spec, idx)
    g_truth, g_other, g_null = pooled(t_truth), pooled(t_other), pooled(data.null_terms)
    return {
        "feed_factor": factor,
        "feeds_mm_s": feeds,
        "truth": truth.name,
        "other": other.name,
        "separation": float(g_other / g_truth),
        "significant": bool(gap_significance(t_other, t_truth, seed=seed)["significant"]),
        "truth_ratio": float(g_truth / g_null),
    }


def separate(
    diagnosis: dict[str, Any],
    episodes: Sequence[EpisodeData],
    factors: Sequence[float] = FEED_FACTORS,
    holes: int = HOLES,
    seed: int = 0,
    progress: Any = None,
) -> dict[str, Any]:
    """For the named model against each alternative with other physics: the separation at each feed, both ways.

    Returns ``{"named", "holes", "factors", "pairs": [{"other", "rows", "weakest", "best"}]}``: ``rows`` per feed
    factor and direction (:func:`separation_at`); ``weakest``: per feed factor, the smaller separation of the two
    directions; ``best``: the ``weakest`` entry with the largest separation, where to drill to tell them apart.
    """
    named, others = models_to_separate(diagnosis)
    chosen = pick_holes(episodes, holes)
    if not chosen:
        raise UserError("no logged episode to take the holes' scenarios from")
    check_factors(factors, chosen)
    replayer = Replayer()
    pairs = []
    for k, other in enumerate(others):
        rows = []
        for j, factor in enumerate(factors):
            for truth, judged in ((named, other), (other, named)):
                rows.append(separation_at(truth, judged, chosen, factor, seed + 1000 * k + j, replayer))
                if progress is not None:
                    progress()
        weakest = [
            {"feed_factor": f, "separation": min(r["separation"] for r in rows if r["feed_factor"] == f)}
            for f in factors
        ]
        best = max(weakest, key=lambda w: w["separation"])
        pairs.append({"other": other.name, "rows": rows, "weakest": weakest, "best": best})
    return {"named": named.name, "holes": [ep.name for ep in chosen], "factors": list(factors), "pairs": pairs}
