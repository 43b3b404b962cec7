"""Features of a trace the gap is computed on: 0.1 s block means and HF power per stage.

Blocks never straddle a stage: each stage's run of samples is cut into blocks of
:data:`~drillgym.eval.diagnosis.channels.BLOCK_SAMPLES`. The block layout comes from the real episode and is
used for every trace replayed from it (rows are aligned).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drillgym.eval.diagnosis.channels import BLOCK_SAMPLES, FORCE, STAGES, WRENCH


@dataclass(frozen=True)
class Blocks:
    """Block layout of one episode.

    Attributes:
        starts: first row of each block, (nb,).
        stage: stage of each block, (nb,).
        row_block: block of each row, (n,).
        blocks_per_stage: number of blocks in each stage, (n_stages,).
    """

    starts: np.ndarray
    stage: np.ndarray
    row_block: np.ndarray
    blocks_per_stage: np.ndarray

    @property
    def n_blocks(self) -> int:
        """Number of blocks."""
        return int(self.starts.size)


def make_blocks(stage: np.ndarray, block_samples: int = BLOCK_SAMPLES) -> Blocks:
    """Cut each run of equal stage into blocks of at most ``block_samples`` rows."""
    stage = np.asarray(stage)
    n = stage.size
    run_start = np.flatnonzero(np.concatenate([[True], stage[1:] != stage[:-1]]))
    run_len = np.diff(np.concatenate([run_start, [n]]))
    starts = np.concatenate(
        [s + np.arange(0, length, block_samples) for s, length in zip(run_start, run_len, strict=True)]
    )
    row_block = np.repeat(np.arange(starts.size), np.diff(np.concatenate([starts, [n]])))
    bstage = stage[starts]
    per_stage = np.bincount(bstage, minlength=len(STAGES))
    return Blocks(starts=starts, stage=bstage, row_block=row_block, blocks_per_stage=per_stage)


def block_means(x: np.ndarray, blocks: Blocks) -> np.ndarray:
    """Mean of each column over each block, ignoring NaN (NaN for a block with no finite value)."""
    finite = np.isfinite(x)
    sums = np.add.reduceat(np.where(finite, x, 0.0), blocks.starts, axis=0)
    counts = np.add.reduceat(finite.astype(float), blocks.starts, axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(counts > 0, sums / np.maximum(counts, 1.0), np.nan)


def hf_power(
    x: np.ndarray, blocks: Blocks, means: np.ndarray | None = None, mask: np.ndarray | None = None
) -> np.ndarray:
    """Mean square of each column about its block means, per stage, (n_stages, C); NaN for an empty stage.

    ``mask`` (nb,) keeps only some blocks (e.g. those without a contact transition).
    """
    m = block_means(x, blocks) if means is None else means
    dev = x - m[blocks.row_block]
    finite = np.isfinite(dev)
    if mask is not None:
        finite &= mask[blocks.row_block][:, None]
    stage_row = blocks.stage[blocks.row_block]
    n_stages = len(STAGES)
    out = np.full((n_stages, x.shape[1]), np.nan)
    for c in range(x.shape[1]):
        ok = finite[:, c]
        s = np.bincount(stage_row[ok], weights=dev[ok, c] ** 2, minlength=n_stages)
        k = np.bincount(stage_row[ok], minlength=n_stages)
        out[:, c] = np.where(k > 1, s / np.maximum(k, 1), np.nan)
    return out


@dataclass(frozen=True)
class Features:
    """What the gap compares: block means of every channel and HF power of the force axes."""

    lf: np.ndarray
    """Block means, (nb, 15)."""
    hf: np.ndarray
    """Force power about the block means per stage, (n_stages, 3) (N²)."""


def smooth3(x: np.ndarray) -> np.ndarray:
    """Three-sample centred moving average (ends kept).

    Zero gain at a third of the F/T rate (33 Hz), where a 20,000 rpm once-per-revolution force aliases,
    so its phase does not leak into block means.
    """
    out = x.copy()
    out[1:-1] = (x[:-2] + x[1:-1] + x[2:]) / 3.0
    return out


def features(lf_rows: np.ndarray, blocks: Blocks, hf_mask: np.ndarray | None = None) -> Features:
    """Features of one trace's channel rows (n, 15) on an episode's block layout (HF over ``hf_mask`` blocks).

    LF: block means, of the 3-sample smoothed F/T (:func:`smooth3`); HF: power of the raw forces about
    their block means.
    """
    raw_means = block_means(lf_rows[:, FORCE], blocks)
    smoothed = lf_rows.copy()
    smoothed[:, WRENCH] = smooth3(lf_rows[:, WRENCH])
    return Features(lf=block_means(smoothed, blocks), hf=hf_power(lf_rows[:, FORCE], blocks, raw_means, hf_mask))


HF_JUMP_N = 0.1
"""A block whose nominal force jumps by more than this between samples (N) holds a contact transition;
its power says more about timing than about vibration, so the HF comparison leaves it out."""


def smooth_blocks(nominal_rows: np.ndarray, blocks: Blocks) -> np.ndarray:
    """Blocks (nb,) of the nominal replay without a force jump above :data:`HF_JUMP_N`."""
    return np.asarray(block_jumps(nominal_rows[:, FORCE], blocks).max(axis=1) <= HF_JUMP_N)


def block_jumps(x: np.ndarray, blocks: Blocks) -> np.ndarray:
    """Largest sample-to-sample change of each column within each block (from its previous sample), (nb, C).

    A jump at a sample time that a replay gets one sample early or late moves the block mean by
    ``jump / block length``: the timing tolerance of a block.
    """
    step = np.abs(np.diff(x, axis=0, prepend=x[:1]))
    step = np.where(np.isfinite(step), step, 0.0)
    return np.maximum.reduceat(step, blocks.starts, axis=0)


def block_lengths(blocks: Blocks) -> np.ndarray:
    """Rows in each block, (nb,)."""
    return np.diff(np.concatenate([blocks.starts, [blocks.row_block.size]]))
