"""What every diagnosis process shares, and the misfit of a set of effects on a set of episodes.

The episodes, their blocks and real features, the nominal replays, the null model, and the
calibration / held-out split; :class:`Evaluator` is the only place replays are run for fitting.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drillgym.envs.effects.base import Effect
from drillgym.envs.effects.registry import EFFECTS
from drillgym.eval.diagnosis.channels import FORCE
from drillgym.eval.diagnosis.episodes import EpisodeData, set_series_positions
from drillgym.eval.diagnosis.evidence import evidence as read_evidence
from drillgym.eval.diagnosis.features import Blocks, Features, features, make_blocks, smooth_blocks
from drillgym.eval.diagnosis.gap import HARDNESS_LEVELS, EpisodeNull, Terms, episode_null, gap_terms, noise_variance
from drillgym.eval.diagnosis.replay import Replayer, SimTrace, seed_for
from drillgym.eval.diagnosis.spectrum import excess_peaks_hz, spectrum_summary

NOISE_DRAWS = 2
"""Replays with sensor noise (and the preset's hardness) per episode, for the noise scale."""

Spec = tuple[tuple[str, tuple[tuple[str, float], ...]], ...]
"""Hashable effect spec: ``((name, ((param, value), ...)), ...)``."""


def make_spec(names: Sequence[str], params: Sequence[dict[str, float]]) -> Spec:
    """Spec from effect names and their parameter dicts."""
    return tuple((n, tuple(sorted(p.items()))) for n, p in zip(names, params, strict=True))


def build(spec: Spec) -> list[Effect]:
    """Candidate effects of a spec."""
    return [EFFECTS[name](**dict(values)) for name, values in spec]


@dataclass
class DiagnosisData:
    """Shared state of one diagnosis (picklable: it is sent once to every worker)."""

    episodes: list[EpisodeData]
    cal: list[int]
    ho: list[int]
    blocks: list[Blocks] = field(default_factory=list)
    real: list[Features] = field(default_factory=list)
    nominal: list[SimTrace] = field(default_factory=list)
    nominal_features: list[Features] = field(default_factory=list)
    nulls: list[EpisodeNull] = field(default_factory=list)
    hf_masks: list[np.ndarray] = field(default_factory=list)
    spectrum: dict[str, Any] = field(default_factory=dict)
    excess_peaks_hz: dict[str, float | None] = field(default_factory=dict)
    """Where the calibration episodes' force residuals ring most above the simulator's own (Hz; a fit's start):
    over all force axes (``all``), the lateral ones and the axial one (:func:`~drillgym.eval.diagnosis.spectrum.excess_peaks_hz`)."""
    null_terms: list[Terms] = field(default_factory=list)
    baseline_terms: list[Terms] = field(default_factory=list)
    null_raw_terms: list[Terms] = field(default_factory=list)
    """The null replays' terms without the per-specimen hardness fit (``gap_terms(..., profile=False)``)."""
    raw_terms: list[Terms] = field(default_factory=list)
    """The real episodes' terms without the per-specimen hardness fit: the gap as the data show it."""
    evidence: dict[str, Any] | None = None
    """What the data say directly of the effects, the fits' starting points (:func:`~drillgym.eval.diagnosis.evidence.evidence`)."""

    @classmethod
    def from_episodes(cls, episodes: list[EpisodeData], cal: list[int], ho: list[int]) -> DiagnosisData:
        """Blocks and real features of every episode (no replays yet); each episode's place in the series."""
        set_series_positions(episodes)
        data = cls(episodes=episodes, cal=cal, ho=ho)
        data.blocks = [make_blocks(ep.stage) for ep in episodes]
        data.real = [features(ep.lf, b) for ep, b in zip(episodes, data.blocks, strict=True)]
        return data

    def add_baseline(self, results: list[BaselineResult]) -> None:
        """Nominal replays and null replays (from :func:`baseline_job`) -> null model and baseline terms."""
        self.nominal = [r.nominal for r in results]
        self.hf_masks = [smooth_blocks(t.lf, b) for t, b in zip(self.nominal, self.blocks, strict=True)]
        self.real = [features(ep.lf, b, m) for ep, b, m in zip(self.episodes, self.blocks, self.hf_masks, strict=True)]
        self.nominal_features = [
            features(t.lf, b, m) for t, b, m in zip(self.nominal, self.blocks, self.hf_masks, strict=True)
        ]
        hard = [{a: features(t.lf, b, m) for a, t in r.hardness.items()} for r, b, m in self._with_blocks(results)]
        noisy = [[features(t.lf, b, m) for t in r.noisy] for r, b, m in self._with_blocks(results)]
        test = [features(r.test.lf, b, m) for r, b, m in self._with_blocks(results)]
        noise_var = noise_variance(self.nominal_features, noisy, self.blocks)
        self.nulls = [
            episode_null(self.nominal_features[i], results[i].nominal.lf, hard[i], noisy[i], noise_var, self.blocks[i])
            for i in range(len(results))
        ]
        n = len(self.episodes)
        self.null_terms = [
            gap_terms(test[i], self.nominal_features[i], self.blocks[i], self.nulls[i]) for i in range(n)
        ]
        real_res = [ep.lf[:, FORCE] - r.nominal.lf[:, FORCE] for ep, r in zip(self.episodes, results, strict=True)]
        null_res = [r.test.lf[:, FORCE] - r.nominal.lf[:, FORCE] for r in results]
        self.spectrum = spectrum_summary(real_res, null_res)
        self.excess_peaks_hz = excess_peaks_hz([real_res[i] for i in self.cal], [null_res[i] for i in self.cal])
        self.baseline_terms = [
            gap_terms(self.real[i], self.nominal_features[i], self.blocks[i], self.nulls[i]) for i in range(n)
        ]
        self.null_raw_terms = [
            gap_terms(test[i], self.nominal_features[i], self.blocks[i], self.nulls[i], profile=False) for i in range(n)
        ]
        self.raw_terms = [
            gap_terms(self.real[i], self.nominal_features[i], self.blocks[i], self.nulls[i], profile=False)
            for i in range(n)
        ]
        self.evidence = read_evidence(self)

    def _with_blocks(self, results: list[BaselineResult]) -> list[tuple[BaselineResult, Blocks, np.ndarray]]:
        return list(zip(results, self.blocks, self.hf_masks, strict=True))


@dataclass
class BaselineResult:
    """Replays of one episode without effects: nominal, specimen hardness levels, noise only, a full null draw."""

    nominal: SimTrace
    hardness: dict[float, SimTrace]
    noisy: list[SimTrace]
    test: SimTrace


def baseline_job(replayer: Replayer, ep: EpisodeData) -> BaselineResult:
    """The replays of one episode the null model needs (nominal, 4 hardness levels, noise, one null draw)."""
    sigma = float(ep.scenario.get("bone_variability", 0.0))
    nominal = replayer.run(ep)
    hardness = {a: replayer.run(ep, hardness=1.0 + a * sigma) if sigma > 0 else nominal for a in HARDNESS_LEVELS}
    noisy = [replayer.run(ep, seed=seed_for(ep.name, k), noise=True) for k in range(NOISE_DRAWS)]
    test = replayer.run(ep, seed=seed_for(ep.name, NOISE_DRAWS), noise=True, variability=True)
    return BaselineResult(nominal, hardness, noisy, test)


class Evaluator:
    """Misfit of effect specs on episodes, with an LRU cache of physics replays."""

    def __init__(self, data: DiagnosisData, replayer: Replayer, cache_size: int = 4) -> None:
        self.data = data
        self.replayer = replayer
        self.cache: OrderedDict[Spec, list[SimTrace | None]] = OrderedDict()
        self.cache_size = cache_size
        self.replays = 0

    def traces(self, spec: Spec, indices: Sequence[int]) -> list[SimTrace]:
        """Replays of the episodes with the spec's effects (sensor-only ones applied to the traces)."""
        effects = build(spec)
        physics = tuple(s for s, e in zip(spec, effects, strict=True) if not e.sensor_only)
        sensors = [e for e in effects if e.sensor_only]
        n = len(self.data.episodes)
        row: list[SimTrace | None] = []
        if physics:
            row = self.cache.setdefault(physics, [None] * n)
            self.cache.move_to_end(physics)
            while len(self.cache) > self.cache_size:
                self.cache.popitem(last=False)
        out = []
        for i in indices:
            if not physics:
                base = self.data.nominal[i]
            else:
                cached = row[i]
                if cached is None:
                    cached = self.replayer.run(self.data.episodes[i], build(physics))
                    self.replays += 1
                    row[i] = cached
                base = cached
            out.append(base.with_sensor_effects(sensors) if sensors else base)
        return out

    def terms(self, spec: Spec, indices: Sequence[int], profile: bool = True) -> list[Terms]:
        """Gap terms of each episode with the spec's effects on.

        ``profile=False``: the raw gap, each specimen taken as preset (:func:`~drillgym.eval.diagnosis.gap.gap_terms`).
        """
        return self.terms_each(spec, indices, (profile,))[0]

    def terms_each(
        self, spec: Spec, indices: Sequence[int], profiles: Sequence[bool] = (True, False)
    ) -> tuple[list[Terms], ...]:
        """:meth:`terms` for each of ``profiles`` (default: profiled and raw), from one replay and feature pass."""
        d = self.data
        assert d.nulls, "add_baseline() first"
        out: tuple[list[Terms], ...] = tuple([] for _ in profiles)
        for i, trace in zip(indices, self.traces(spec, indices), strict=True):
            f = features(trace.lf, d.blocks[i], d.hf_masks[i])
            for terms, profile in zip(out, profiles, strict=True):
                terms.append(gap_terms(d.real[i], f, d.blocks[i], d.nulls[i], profile=profile))
        return out


def split_episodes(episodes: list[EpisodeData], seed: int = 0) -> tuple[list[int], list[int]]:
    """Calibration and held-out halves, alternating within each controller (so both halves see each)."""
    rng = np.random.default_rng(seed)
    cal: list[int] = []
    ho: list[int] = []
    by_controller: dict[str, list[int]] = {}
    for i, ep in enumerate(episodes):
        by_controller.setdefault(ep.controller, []).append(i)
    flip = 0
    for name in sorted(by_controller):
        idx = list(rng.permutation(by_controller[name]))
        for k, i in enumerate(idx):
            ((cal, ho)[(k + flip) % 2]).append(int(i))
        flip += len(idx)
    return sorted(cal), sorted(ho)
