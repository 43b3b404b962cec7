"""The gap between a real episode and a replay, in units of the simulator's own scatter.

The simulator knows two kinds of scatter it does not model as effects: sensor noise, and the
specimen-to-specimen hardness of the bone (``bone_variability``: every episode's bone is a factor
``k ~ N(1, σ_k²)`` harder). A gap is only a gap beyond those:

* **Hardness is profiled out** per episode. The replay's response ``D(a)`` to a specimen ``a`` σ_k harder
  is tabulated from replays at ``a = ±1, ±2`` (block means, piecewise linear in a); the ``a`` minimising
  ``Σ w (r − D(a))² + a²`` (a grid over ±3 σ_k refined by a parabola) is taken and ``r − D(a)`` is what is
  left; ``a²`` is added to the misfit (a specimen far from its preset costs like a σ-outlier).
* **Noise** sets the scale: each LF block's squared residual is divided by the noise variance of that
  channel and stage (from replays with noise and no hardness scatter) plus the channel's floor plus a
  share of the curvature (what the quadratic leaves out) plus, for the F/T, a one-sample timing
  tolerance of the block's largest jump (a contact lost one sample later).
* **HF**: the log of the real HF power over the expected one (the replay's plus the sensor noise's),
  corrected for the profiled hardness (the replay's own chatter moves with it), squared, over its
  sampling variance, counted once per block of the stage.

So every term is ≈ 1 where the simulator explains the data (0 for channels it reproduces exactly, the
joint angles), and the sum ``J`` of an episode's terms is a χ²-like misfit for fitting and ranking.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from drillgym.eval.diagnosis.channels import (
    ALL_CHANNELS,
    HF_LOG_VAR_FLOOR,
    HF_POWER_FLOOR_N2,
    LF_CHANNELS,
    LF_FLOOR,
    STAGES,
)
from drillgym.eval.diagnosis.features import Blocks, Features, block_jumps, block_lengths

N_LF = len(LF_CHANNELS)
PROFILE_GRID = np.linspace(-3.0, 3.0, 25)
"""Specimen hardness offsets (σ_k) the profile searches."""
HARDNESS_LEVELS = (-2.0, -1.0, 1.0, 2.0)
"""Hardness offsets (σ_k) replayed to tabulate each episode's response to its specimen."""
CUBIC_SHARE = 0.3
"""Share of the ±1 σ_k curvature kept as model error (what the piecewise-linear table leaves out)."""
N_FT = 6
"""The F/T columns come first."""
N_CELLS = (len(STAGES), len(ALL_CHANNELS))
_FLOOR2 = np.array([LF_FLOOR[c] ** 2 for c in LF_CHANNELS])


@dataclass
class EpisodeNull:
    """The simulator's own scatter for one episode.

    Attributes:
        var: variance of each block-mean residual (units²), (nb, 15): noise + floor + hardness curvature.
        resp: block-mean response to a specimen ``a`` σ_k harder, at each a of :data:`PROFILE_GRID`, (na, nb, 15).
        hf_noise: noise power the sensor adds to each force axis per stage (N²), (6, 3).
        hf_logvar: variance of the log of an HF power per stage, (6, 3).
        hf_sens: change of the log of the expected HF power with a +1 σ_k specimen, (6, 3).
    """

    var: np.ndarray
    resp: np.ndarray
    hf_noise: np.ndarray
    hf_logvar: np.ndarray
    hf_sens: np.ndarray


def noise_variance(nominal: list[Features], noisy: list[list[Features]], blocks: list[Blocks]) -> np.ndarray:
    """Pooled variance of block means under sensor noise alone, per stage and LF channel, (6, 15)."""
    n_st = len(STAGES)
    sums = np.zeros((n_st, N_LF))
    counts = np.zeros((n_st, N_LF))
    for nom, ds, b in zip(nominal, noisy, blocks, strict=True):
        for d in ds:
            r2 = (d.lf - nom.lf) ** 2
            ok = np.isfinite(r2)
            np.add.at(sums, b.stage, np.where(ok, r2, 0.0))
            np.add.at(counts, b.stage, ok)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1.0), 0.0)


def episode_null(
    nominal: Features,
    nominal_rows: np.ndarray,
    hardness: dict[float, Features],
    noisy: list[Features],
    noise_var: np.ndarray,
    b: Blocks,
) -> EpisodeNull:
    """Null model of one episode.

    From its nominal replay (features and rows), its replays at specimen hardness offsets (in σ_k:
    ``{−2: ..., −1: ..., 1: ..., 2: ...}``) and its noise-only replays.
    """
    levels = sorted({0.0, *hardness})
    table = np.stack([nominal.lf if a == 0.0 else hardness[a].lf for a in levels]) - nominal.lf[None]
    table = np.nan_to_num(table)
    resp = np.stack([_interp_response(levels, table, a) for a in PROFILE_GRID])
    curv = 0.5 * (_interp_response(levels, table, 1.0) + _interp_response(levels, table, -1.0))
    var = noise_var[b.stage] + _FLOOR2[None, :] + (CUBIC_SHARE * curv) ** 2
    # F/T only: a contact that starts or ends one sample earlier or later (joint angles and the tracker
    # follow the commands exactly in time, so they get no such tolerance).
    tolerance = block_jumps(nominal_rows[:, :N_FT], b) / block_lengths(b)[:, None]
    var[:, :N_FT] += tolerance**2
    n_st = len(STAGES)
    noise = np.zeros((n_st, 3))
    if noisy:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a stage no episode reached
            noise = np.clip(np.nan_to_num(np.nanmean(np.stack([d.hf for d in noisy]), axis=0) - nominal.hf), 0.0, None)
    samples = np.bincount(b.stage[b.row_block], minlength=n_st).astype(float)
    per_stage = np.where(samples > 1, 2.0 / np.maximum(samples - b.blocks_per_stage, 1.0), np.inf)
    logvar = np.maximum(per_stage, HF_LOG_VAR_FLOOR)[:, None] * np.ones((1, 3))
    # The replay's own HF (the cutting/resting chatter of the bottom contact) moves with the hardness.
    hi, lo = hardness.get(1.0, nominal), hardness.get(-1.0, nominal)
    with np.errstate(invalid="ignore", divide="ignore"):
        lh, ls, ln = (np.log(f.hf + noise + HF_POWER_FLOOR_N2) for f in (hi, lo, nominal))
    hf_sens = np.nan_to_num(0.5 * (lh - ls))
    logvar = logvar + np.nan_to_num(0.5 * (lh + ls) - ln) ** 2
    return EpisodeNull(var=var, resp=resp, hf_noise=noise, hf_logvar=logvar, hf_sens=hf_sens)


def _interp_response(levels: list[float], table: np.ndarray, a: float) -> np.ndarray:
    """Response at hardness offset ``a`` (σ_k), piecewise linear in a, extrapolated from the end segments."""
    x = np.asarray(levels)
    j = int(np.clip(np.searchsorted(x, a) - 1, 0, len(x) - 2))
    w = (a - x[j]) / (x[j + 1] - x[j])
    return (1.0 - w) * table[j] + w * table[j + 1]


@dataclass
class Terms:
    """Gap terms of one or more episodes, summed per (stage, channel) cell.

    Attributes:
        cell_sum: sum of the normalised squared gaps in each cell, (6, 18).
        cell_n: number of terms in each cell, (6, 18).
        rms_sum: sum of the squared raw gaps (channel units²; HF: RMS difference, N²) per cell, (6, 18).
        prior_sum: sum of the squared fitted hardness offsets (in σ_k) of the episodes.
        prior_n: number of episodes summed.
        hardness: the fitted hardness offset of a single episode (in σ_k).
    """

    cell_sum: np.ndarray
    cell_n: np.ndarray
    rms_sum: np.ndarray
    prior_sum: float = 0.0
    prior_n: float = 0.0
    hardness: float = 0.0

    @property
    def j(self) -> float:
        """χ²-like misfit: the sum of all terms plus the hardness priors."""
        return float(self.cell_sum.sum()) + self.prior_sum

    @property
    def n(self) -> float:
        """Number of terms (each episode's hardness prior counts as one)."""
        return float(self.cell_n.sum()) + self.prior_n

    @staticmethod
    def zeros() -> Terms:
        """Empty terms (to add episodes into)."""
        return Terms(np.zeros(N_CELLS), np.zeros(N_CELLS), np.zeros(N_CELLS))

    def __add__(self, other: Terms) -> Terms:
        return Terms(
            self.cell_sum + other.cell_sum,
            self.cell_n + other.cell_n,
            self.rms_sum + other.rms_sum,
            self.prior_sum + other.prior_sum,
            self.prior_n + other.prior_n,
        )


def pooled(terms: list[Terms]) -> float:
    """Σ J / Σ N."""
    j = sum(t.j for t in terms)
    n = sum(t.n for t in terms)
    return j / n if n > 0 else float("nan")


def gap_terms(real: Features, sim: Features, blocks: Blocks, null: EpisodeNull, profile: bool = True) -> Terms:
    """Terms of one episode: ``real`` against the replay ``sim``.

    ``profile``: the specimen's hardness is profiled out (the default, see the module docstring); without it the
    terms are the raw gap, the specimen taken as preset (``a = 0``, no prior term), as the data show it before
    any nuisance parameter is fitted.
    """
    out = Terms.zeros()
    r = real.lf - sim.lf
    ok = np.isfinite(r)
    r = np.where(ok, r, 0.0)
    w = np.where(ok, 1.0 / null.var, 0.0)
    if profile:
        a, resp = _profile_hardness(r, w, null)
        out.prior_sum, out.prior_n = a * a, 1.0
    else:
        a, resp = 0.0, np.zeros_like(r)
    resid = r - resp
    z = w * resid**2
    np.add.at(out.cell_sum[:, :N_LF], blocks.stage, z)
    np.add.at(out.cell_n[:, :N_LF], blocks.stage, ok.astype(float))
    np.add.at(out.rms_sum[:, :N_LF], blocks.stage, np.where(ok, resid**2, 0.0))
    out.hardness = a
    expected = sim.hf + null.hf_noise
    h = np.log((real.hf + HF_POWER_FLOOR_N2) / (expected + HF_POWER_FLOOR_N2)) - a * null.hf_sens
    zh = h**2 / null.hf_logvar
    okh = np.isfinite(zh)
    weight = blocks.blocks_per_stage[:, None] * okh
    out.cell_sum[:, N_LF:] = np.where(okh, zh, 0.0) * weight
    out.cell_n[:, N_LF:] = weight
    rms_diff2 = (np.sqrt(np.abs(real.hf)) - np.sqrt(np.abs(expected))) ** 2
    out.rms_sum[:, N_LF:] = np.where(okh, rms_diff2, 0.0) * weight
    return out


def _profile_hardness(r: np.ndarray, w: np.ndarray, null: EpisodeNull) -> tuple[float, np.ndarray]:
    """The specimen offset ``a`` (σ_k) minimising ``Σ w (r − D(a))² + a²`` and its response ``D(a)``, (nb, 15)."""
    cost = (w[None] * (r[None] - null.resp) ** 2).sum(axis=(1, 2)) + PROFILE_GRID**2
    k = int(np.argmin(cost))
    a = float(PROFILE_GRID[k])
    if 0 < k < PROFILE_GRID.size - 1:  # parabola through the best grid point and its neighbours
        c0, c1, c2 = cost[k - 1], cost[k], cost[k + 1]
        denom = c0 - 2.0 * c1 + c2
        if denom > 0:
            step = 0.5 * (c0 - c2) / denom
            a += step * float(PROFILE_GRID[1] - PROFILE_GRID[0])
            k0 = k + (1 if step > 0 else -1)
            frac = abs(step)
            return a, (1 - frac) * null.resp[k] + frac * null.resp[k0]
    return a, null.resp[k]
