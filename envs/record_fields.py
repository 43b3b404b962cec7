"""A named field of an episode's record (:mod:`drillgym.envs.episode_state`), declared once with its unit and frame.

The core declares its own fields; a compiled effect declares the parameters and state its kernel hook reads
beside its Python hook, in its own module (:attr:`drillgym.envs.effects.base.Effect.kernel_params`,
:attr:`~drillgym.envs.effects.base.Effect.kernel_state`); the records are assembled from both.
"""

from __future__ import annotations

from typing import NamedTuple


class Field(NamedTuple):
    """One named field: its name, NumPy type, shape (``()`` for a scalar) and what it holds (unit, frame)."""

    name: str
    dtype: str
    shape: tuple[int, ...]
    doc: str


def float_field(name: str, doc: str, *shape: int) -> Field:
    """A ``float64`` field (a scalar without ``shape``)."""
    return Field(name, "f8", shape, doc)


def int_field(name: str, doc: str) -> Field:
    """An ``int64`` scalar (a count or a code)."""
    return Field(name, "i8", (), doc)


def flag_field(name: str, doc: str) -> Field:
    """A boolean scalar."""
    return Field(name, "?", (), doc)
