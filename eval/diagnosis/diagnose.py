"""The diagnosis: where the sim-to-real gap lies, which unmodelled effect explains it, how far it shrinks.

:func:`diagnose` takes checked real episodes and returns the ``diagnosis.json`` dict. Steps: split the
episodes into calibration and held-out halves; replay every episode nominally and with the sim's own
scatter (null model); test whether there is a gap at all; fit every candidate effect on the
calibration half and score it on the held-out half; fit pairs of the best candidates when one is not
enough (forward selection, then the best pairs refitted jointly); name what is surely worth naming
(the scores and bars: :mod:`drillgym.eval.diagnosis.rank`, the pair rule and guards: :mod:`drillgym.eval.diagnosis.pairs`;
the decision on them: :mod:`drillgym.eval.diagnosis.verdict`).
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

from tqdm import tqdm

from drillgym.envs.effects.registry import DIAGNOSIS_CANDIDATES, EFFECTS, physics_of
from drillgym.envs.errors import UserError
from drillgym.eval.diagnosis.context import DiagnosisData, split_episodes
from drillgym.eval.diagnosis.episodes import EpisodeData
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import pooled
from drillgym.eval.diagnosis.intervals import off_point_inside, parameter_intervals
from drillgym.eval.diagnosis.leftover import leftover_search
from drillgym.eval.diagnosis.location import location_check
from drillgym.eval.diagnosis.pairs import PAIR_TRY_RESIDUAL, pair_roles, possible_second_effects, second_effect_evidence
from drillgym.eval.diagnosis.pool import Runner
from drillgym.eval.diagnosis.rank import (
    RESCUE_CI_LOW_MIN,
    ModelScore,
    alternatives,
    baseline_score,
    nameable,
    score_models,
    singles_by_name,
)
from drillgym.eval.diagnosis.verdict import Decision, best_single, decide, gap_location, summary
from drillgym.eval.diagnosis.where import gap_map, gap_significance, locate
from drillgym.eval.progress import bar_size

MIN_EPISODES = 4
"""At least two calibration and two held-out episodes."""


@dataclass
class DiagnoseOptions:
    """How to run a diagnosis."""

    workers: int = os.cpu_count() or 1
    """Processes (each runs its own simulator)."""
    candidates: tuple[str, ...] = DIAGNOSIS_CANDIDATES
    """Candidate effects to try (default: the whole library)."""
    pair_seeds: int = 2
    """Pairs are built on top of this many of the best singles (forward selection from each)."""
    refit_pairs: int = 2
    """This many of the best pairs (and the pair of the two best nameable singles) are then refitted
    with every parameter free (:func:`~drillgym.eval.diagnosis.fit.refit_jointly`); 0 keeps forward selection."""
    seed: int = 0
    """Seed of the split and the bootstrap."""
    progress: bool = True
    """Show a progress bar (stderr)."""


@dataclass
class Diagnosis:
    """A diagnosis: the ``diagnosis.json`` dict and the state behind it (for the report's figures)."""

    result: dict[str, Any]
    data: DiagnosisData
    scores: list[ModelScore]


def diagnose(episodes: list[EpisodeData], options: DiagnoseOptions | None = None) -> dict[str, Any]:
    """Diagnose the gap between ``episodes`` (real) and the simulator; see the module docstring."""
    return run_diagnosis(episodes, options).result


def run_diagnosis(episodes: list[EpisodeData], options: DiagnoseOptions | None = None) -> Diagnosis:
    """:func:`diagnose`, keeping the episodes' replays and the model scores."""
    opt = options or DiagnoseOptions()
    if len(episodes) < MIN_EPISODES:
        raise UserError(f"{len(episodes)} usable episode(s); the diagnosis needs at least {MIN_EPISODES}")
    t0 = time.perf_counter()
    cal, ho = split_episodes(episodes, opt.seed)
    data = DiagnosisData.from_episodes(episodes, cal, ho)
    with Runner(opt.workers) as runner:  # the workers start once and serve every phase
        bar = tqdm(
            total=len(episodes) + len(opt.candidates),
            desc="diagnose",
            file=sys.stderr,
            disable=None if opt.progress else True,
            **bar_size(sys.stderr),
        )
        timings: dict[str, float] = {}
        bar.set_postfix_str("replaying (nominal + null)")
        results: list[Any] = [None] * len(episodes)
        for i, r in runner.baselines(data):
            results[i] = r
            bar.update()
        data.add_baseline(results)
        timings["baseline_s"] = time.perf_counter() - t0
        significance = gap_significance(data.baseline_terms, data.null_terms, opt.seed)
        before = [data.baseline_terms[i] for i in ho]
        null = [data.null_terms[i] for i in ho]

        bar.set_postfix_str("fitting single effects")
        singles = _run_fits(runner, data, [((n,), None) for n in opt.candidates], bar)
        scores = score_models(singles, before, null, opt.seed)
        timings["singles_s"] = time.perf_counter() - t0 - timings["baseline_s"]
        pairs: list[FitResult] = []
        g_null = pooled(null)
        if significance["significant"] and scores and scores[0].after >= PAIR_TRY_RESIDUAL * g_null:
            # Forward selection from the best singles: every other candidate is fitted on top of each.
            s0 = baseline_score(before)
            # A random effect (fitted per episode) takes no part in pairs: it is fitted alone only.
            shared = [n for n in opt.candidates if not EFFECTS[n].per_episode]
            by_score = [s for s in scores if s.fit.names[0] in shared]
            seeds = [s for s in by_score if s.score < s0][: opt.pair_seeds] or by_score[:1]
            jobs = pair_jobs(seeds, shared)
            if jobs:
                bar.total += len(jobs)
                bar.set_postfix_str("fitting pairs")
                pairs = _run_fits(runner, data, jobs, bar)
                scores = score_models(singles + pairs, before, null, opt.seed)
                refits = _refit_jobs(scores, pairs, s0, opt.refit_pairs)
                if refits:
                    bar.total += len(refits)
                    bar.set_postfix_str("refitting the best pairs jointly")
                    models = [(names, starts) for names, starts, _ in refits]
                    out = _collect(runner.refits(data, models), len(refits), bar)
                    for (_, _, i), r in zip(refits, out, strict=True):
                        if not r.error and r.cal_objective <= pairs[i].cal_objective:
                            r.samples = _merged_samples(pairs[i], r)
                            pairs[i] = r
                singles = [_best_anywhere(f, pairs) for f in singles]
                scores = score_models(singles + pairs, before, null, opt.seed)
        timings["pairs_s"] = time.perf_counter() - t0 - timings["baseline_s"] - timings["singles_s"]
        verdict, chosen, location, guard, off_point, scores, rescue = _name(
            runner, data, significance, singles + pairs, scores, before, null, opt.seed, bar
        )
    timings["polish_s"] = time.perf_counter() - t0 - sum(timings.values())
    bar.close()
    named = [] if chosen is None else list(chosen.fit.names)
    alts, seconds = [], []
    evidence: dict[str, Any] | None = None
    leftover: dict[str, Any] | None = None
    if chosen is not None:
        leftover = {
            "ratio": chosen.leftover_ratio,
            "cells": locate(chosen.fit.ho_terms, null),
        }
        alts = alternatives(scores, chosen, baseline_score(before))
        seconds = possible_second_effects(scores, chosen, pooled(null), null)
        if len(chosen.fit.names) == 2:
            first, second = pair_roles(chosen, singles_by_name(scores))
            if first is not None:
                evidence = second_effect_evidence(chosen, first, second, null)
    searched = None if chosen is None else leftover_search(chosen, scores, null)
    located = location_check(data)
    timings["total_s"] = time.perf_counter() - t0
    result = {
        "verdict": verdict,
        "named": named,
        "summary": summary(verdict, chosen, location, alts, seconds, leftover, located["raw"][0]),
        "leftover": leftover,
        "leftover_search": searched,
        "per_episode": None if chosen is None else chosen.fit.per_episode,
        "single_guard": guard,
        "off_point_guard": off_point or None,
        "rescue": rescue,
        "effects": [s.to_json() for s in scores],
        "alternatives": alts,
        "possible_second_effects": seconds,
        "second_effect_evidence": evidence,
        "where": {
            "all_episodes": gap_map(data.baseline_terms, data.null_terms),
            "heldout_after": None if chosen is None else gap_map(chosen.fit.ho_terms, null),
            "largest_excess": located["after_specimen_fit"],
            "frequency": data.spectrum,
        },
        "location": location,
        "location_check": located,
        "significance": significance,
        "episodes": {
            "n": len(episodes),
            "calibration": [episodes[i].name for i in cal],
            "heldout": [episodes[i].name for i in ho],
            "repairs": {ep.name: ep.repairs for ep in episodes if ep.repairs},
            "specimen_hardness_sigma": {ep.name: data.baseline_terms[i].hardness for i, ep in enumerate(episodes)},
        },
        "timing": {**timings, "workers": runner.workers, "candidates": len(opt.candidates), "pairs": len(pairs)},
    }
    return Diagnosis(result, data, scores)


def _name(
    runner: Runner,
    data: DiagnosisData,
    significance: dict[str, Any],
    fits: list[FitResult],
    scores: list[ModelScore],
    before: list[Any],
    null: list[Any],
    seed: int,
    bar: tqdm,
) -> Decision:
    """Decide on ``scores`` (of ``fits``), refine the named model (:func:`_polish`), decide again, and bound its parameters.

    The named model's parameters come from the best fit found anywhere in the search; every model gets
    its parameters' 95 % intervals (:mod:`drillgym.eval.diagnosis.intervals`), and a named model with an
    effect whose intervals all contain its off point is not named (``off_point``). A pair refused so for one of
    its effects falls back to its other effect alone, refined and decided on again without the pair.
    """
    verdict, chosen, location, guard = decide(significance, scores, before, data, null)
    # The named model is refined and decided on again. Where a significant gap has nothing named, so is the best
    # single effect (its search may have stopped short of its valley); what is named after that second look must
    # be surely better than nothing: the low end of its shrink interval at least RESCUE_CI_LOW_MIN.
    rescue = chosen is None and verdict == "unexplained"
    target = best_single(scores) if rescue else chosen
    record: dict[str, Any] | None = None
    if target is not None and target.fit.per_episode is None:  # a random effect's fit is every episode's own
        bar.set_postfix_str("refining the best single" if rescue else "refining the named model")
        fits = _repolished(runner, data, fits, next(i for i, f in enumerate(fits) if f is target.fit), bar)
        scores = score_models(fits, before, null, seed)
        verdict, chosen, location, guard = decide(significance, scores, before, data, null)
        if rescue:
            record = _rescue_record(target.name, chosen)
            if chosen is not None and not record["named"]:
                chosen.named, chosen = False, None
                verdict, location = "unexplained", gap_location(data)
    _bound(scores, seed)
    off_point = [] if chosen is None else off_point_inside(chosen.intervals, chosen.fit.names)
    if chosen is not None and off_point:  # not told apart from its absence: not named as it is
        refused, chosen.named, chosen = chosen.fit, False, None
        keep = tuple(n for n in refused.names if n not in off_point)
        single = next((i for i, f in enumerate(fits) if f.names == keep), None) if len(keep) == 1 else None
        if single is not None:
            # A pair whose other effect is not told apart from its absence is its first effect alone: that single
            # is decided on again, refined from the pair's values for it (which may be better than its own fit's,
            # as the pair's are refined and the single's are not).
            fits = _repolished(runner, data, fits, single, bar)
            scores = score_models(fits, before, null, seed)
            verdict, chosen, location, guard = decide(
                significance, [s for s in scores if s.fit is not refused], before, data, null
            )
            _bound(scores, seed)
            if chosen is not None and (
                chosen.fit is not fits[single] or off_point_inside(chosen.intervals, chosen.fit.names)
            ):  # the fallback is the single, nameable on its own, or nothing
                chosen.named, chosen = False, None
        if chosen is None:
            verdict, location = "unexplained", gap_location(data)
    return Decision(verdict, chosen, location, guard, off_point, scores, record)


def _rescue_record(effect: str, decided: ModelScore | None) -> dict[str, Any]:
    """What came of refining the best single ``effect`` on a gap that had nothing named (``Decision.rescue``)."""
    out: dict[str, Any] = {"effect": effect, "decided": None, "named": False, "reason": None}
    if decided is None:
        return out
    out.update(decided=decided.name, named=decided.ci_low >= RESCUE_CI_LOW_MIN)
    if not out["named"]:
        out["reason"] = (
            f"named only after the best single was refined, and its shrink interval starts at "
            f"{100 * decided.ci_low:.0f} %, under the {100 * RESCUE_CI_LOW_MIN:.0f} % such a second look asks"
        )
    return out


def _bound(scores: list[ModelScore], seed: int) -> None:
    """Every model's parameter intervals (a random effect's come with its fit)."""
    for s in scores:
        if not s.intervals:
            s.intervals = s.fit.intervals if s.fit.intervals is not None else parameter_intervals(s.fit.samples, seed)


def _repolished(runner: Runner, data: DiagnosisData, fits: list[FitResult], k: int, bar: tqdm) -> list[FitResult]:
    """``fits`` with its ``k``-th fit refined (:func:`_polish`); one more step on the progress bar."""
    bar.total += 1
    out = list(fits)
    out[k] = _polish(runner, data, fits[k], fits, bar)
    return out


def _polish(runner: Runner, data: DiagnosisData, fit: FitResult, fits: list[FitResult], bar: tqdm) -> FitResult:
    """``fit`` refitted with every parameter free from the best of its own values and theirs in ``fits``.

    A search that fitted the same effects inside a larger model (a pair's joint refit, say) may have found
    better values for them than their own fit did; the compass search from the best start settles them.
    The result keeps every evaluated point of both searches (for the parameters' intervals); the
    refit replaces the fit only if its calibration gap is not higher.
    """
    names = fit.names
    starts = [fit.params]
    for f in fits:
        if f is fit or f.error or not set(names) <= set(f.names):
            continue
        start = [f.params[f.names.index(n)] for n in names]
        if start not in starts:
            starts.append(start)
    (r,) = _collect(runner.refits(data, [(names, starts)]), 1, bar)
    better = r if not r.error and r.cal_objective <= fit.cal_objective else fit
    better.samples = _merged_samples(fit, r)
    return better


def _best_anywhere(single: FitResult, pairs: list[FitResult]) -> FitResult:
    """``single``, or the best pair holding it with the other effect switched off, where that fits better.

    Such a pair is the single effect itself (the other at every parameter's off value), fitted from other starts
    and refitted jointly: its values are the single's best fit found anywhere. The single then takes them, its
    held-out terms and its evaluated points (the pair's, the other effect dropped, with its own).
    """
    if single.error or len(single.names) != 1:
        return single
    name = single.names[0]
    best = single
    for p in pairs:
        if p.error or name not in p.names or p.cal_objective >= best.cal_objective:
            continue
        k = p.names.index(name)
        if _off((p.names[1 - k], tuple(p.params[1 - k].items()))):
            best = p
    if best is single:
        return single
    k = best.names.index(name)
    own = [(spec[k : k + 1], j, n) for spec, j, n in best.samples if _off(spec[1 - k])]
    return replace(
        single,
        params=[dict(best.params[k])],
        cal_objective=best.cal_objective,
        ho_terms=best.ho_terms,
        ho_raw_terms=best.ho_raw_terms,
        samples=list({sp: (sp, j, n) for sp, j, n in [*single.samples, *own]}.values()),
    )


def _off(effect_spec: tuple[str, tuple[tuple[str, float], ...]]) -> bool:
    """Is an effect of a spec (``(name, ((param, value), ...))``) at every parameter's off value?"""
    name, values = effect_spec
    given = dict(values)
    return all(given.get(q.name, q.default) == q.default for q in EFFECTS[name].params)


def _merged_samples(a: FitResult, b: FitResult) -> list[Any]:
    """The evaluated points of two fits of the same model on the same episodes, each point once."""
    return list({spec: (spec, j, n) for spec, j, n in [*a.samples, *b.samples]}.values())


def pair_jobs(seeds: list[ModelScore], shared: list[str]) -> list[tuple[tuple[str, str], list[dict[str, float]]]]:
    """Forward selection's fits: every candidate of ``shared`` on top of each seed single (held at its fit).

    A candidate of the seed's own physics (:func:`~drillgym.envs.effects.registry.physics_of`: a trend form on its
    static one) is not paired with it: two forms of one physics are one effect, and the pair would only let one
    patch the other's form.
    """
    return [
        ((s.fit.names[0], n), [s.fit.params[0], {}])
        for s in seeds
        for n in shared
        if physics_of(n) != physics_of(s.fit.names[0])
    ]


def _refit_jobs(
    scores: list[ModelScore], pairs: list[FitResult], s0: float, top: int
) -> list[tuple[tuple[str, ...], list[list[dict[str, float]]], int]]:
    """``(names, starts, index in pairs)`` of the pairs to refit jointly.

    The ``top`` best-scoring pairs, and the pair of the two best singles that are nameable on their own
    (two effects that each explain the data may be confounded, or both present). Starts: the forward
    fit, the other order's forward fit where there is one, and the two effects' single fits side by side.
    """
    if top <= 0:
        return []
    singles = singles_by_name(scores)
    index = {p.names: i for i, p in enumerate(pairs) if not p.error}
    wanted = [tuple(s.fit.names) for s in scores if len(s.fit.names) == 2 and s.fit.names in index][:top]
    both = tuple(n for n, s in singles.items() if nameable(s, s0))[:2]
    if len(both) == 2 and both in index and both not in wanted:
        wanted.append(both)
    jobs: list[tuple[tuple[str, ...], list[list[dict[str, float]]], int]] = []
    for names in wanted:
        i = index[names]
        starts = [pairs[i].params]
        other = index.get(names[::-1])
        if other is not None:  # the other order's forward fit
            starts.append(pairs[other].params[::-1])
        if all(n in singles for n in names):
            starts.append([singles[n].fit.params[0] for n in names])
        jobs.append((names, starts, i))
    return jobs


def _run_fits(runner: Runner, data: DiagnosisData, jobs: list[Any], bar: tqdm) -> list[FitResult]:
    return _collect(runner.fits(data, jobs), len(jobs), bar)


def _collect(results: Iterable[tuple[int, FitResult]], n: int, bar: tqdm) -> list[FitResult]:
    """The ``n`` fits of ``(index, fit)`` pairs arriving in any order, in index order (one bar tick each)."""
    out: list[Any] = [None] * n
    for k, r in results:
        out[k] = r
        bar.update()
    return out


__all__ = ["DiagnoseOptions", "Diagnosis", "diagnose", "pooled", "run_diagnosis"]
