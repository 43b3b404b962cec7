"""Episode seeds by purpose: judging, tuning, training and selection never share a specimen.

``reset(seed=k)`` draws the specimen and every noise of an episode from ``k`` alone, whatever the scenario,
so two jobs that pass the same ``k`` drill the same specimen. A tuner or a trainer that saw the judge's
episode seeds would be judged on specimens it was tuned on. The project's jobs therefore never pass a
user's seed number to ``reset`` directly: they map it into the namespace of their purpose,

    episode seed = purpose · 2^48 + index,   0 ≤ index < 2^48,

so the seeds of two purposes are different integers by construction, whatever numbers a user gives
(and the generators Gymnasium builds from them, ``SeedSequence(seed)``, are different streams). The
judge's namespace is purpose 0: judge seed ``i`` is plain ``reset(seed=i)``, so ``drillgym bench --seeds
20`` drills seeds 0..19 as it always has. A job whose episodes come from a generator (a training run's
draws) takes the generator from :func:`stream` and its seeds from :func:`draw_seed`; a training run's
workers take independent streams keyed by (run seed, rank) (:func:`training_stream`), never ``seed + rank``.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

from drillgym.envs.errors import UserError

INDEX_BITS = 48
INDEX_LIMIT = 1 << INDEX_BITS
"""An index within a namespace is in [0, 2^48): seeds stay below 2^51, inside int64 for logs and tables."""


class Purpose(IntEnum):
    """What an episode is for; each purpose has its own seed namespace."""

    JUDGE = 0
    """Benchmark suites and seed reports (``drillgym bench``, ``train --seeds``' judging)."""
    TUNE = 1
    """Classical tuners (``drillgym tune-entry``, ``drillgym tune-table``)."""
    TRAIN = 2
    """Training episodes of learnt policies."""
    SELECT = 3
    """Evaluation and model selection during and after training (held-in episodes)."""


def episode_seed(purpose: Purpose, index: int) -> int:
    """The ``reset`` seed of episode ``index`` of ``purpose`` (judge: ``index`` itself).

    Raises:
        ValueError: ``index`` outside [0, 2^48).
    """
    index = int(index)
    if not 0 <= index < INDEX_LIMIT:
        raise UserError(f"seed index {index} of purpose {Purpose(purpose).name.lower()} must be in [0, 2^{INDEX_BITS})")
    return (int(purpose) << INDEX_BITS) | index


def purpose_of(seed: int) -> Purpose:
    """The purpose whose namespace ``seed`` lies in.

    Raises:
        ValueError: a negative seed, or one above every namespace.
    """
    seed = int(seed)
    if seed < 0 or (seed >> INDEX_BITS) >= len(Purpose):
        raise UserError(f"seed {seed} lies in no purpose's namespace")
    return Purpose(seed >> INDEX_BITS)


def in_namespace(seed: int, purpose: Purpose) -> bool:
    """Whether ``seed`` lies in ``purpose``'s namespace (False for any other integer, never an error)."""
    return int(seed) >= 0 and (int(seed) >> INDEX_BITS) == int(purpose)


def stream(purpose: Purpose, *keys: int) -> np.random.Generator:
    """An independent generator for ``purpose`` and ``keys`` (e.g. a run's seed and a worker's rank).

    Built from ``SeedSequence([purpose, *keys])``: different keys give independent streams, unlike
    ``seed + rank``, where runs ``s`` and ``s + 1`` share every worker but one.
    """
    if any(int(k) < 0 for k in keys):
        raise UserError(f"stream keys must be >= 0, got {keys}")
    return np.random.default_rng(np.random.SeedSequence([int(purpose), *(int(k) for k in keys)]))


def training_stream(keys: tuple[int, ...], seed: int | None) -> np.random.Generator:
    """The generator of a training wrapper's draws: the training :func:`stream` of ``keys`` and ``seed``.

    ``keys`` are a run's seed and a worker's rank; the reset's ``seed`` is appended when one is given.
    """
    return stream(Purpose.TRAIN, *keys, *(() if seed is None else (seed,)))


def draw_seed(rng: np.random.Generator, purpose: Purpose) -> int:
    """A random episode seed in ``purpose``'s namespace, drawn from ``rng``."""
    return episode_seed(purpose, int(rng.integers(INDEX_LIMIT)))
