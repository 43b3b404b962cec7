"""Bit-for-bit comparison of env outputs, for the determinism and step-equivalence tests."""

from __future__ import annotations

import math
import numbers
from typing import Any

import numpy as np


def first_difference(a: Any, b: Any, path: str = "") -> str | None:
    """Path of the first quantity that is not bit-for-bit identical (dtype and signs of zero included)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return f"{path} keys {sorted(set(a) ^ set(b))}"
        for k in a:
            diff = first_difference(a[k], b[k], f"{path}.{k}" if path else k)
            if diff is not None:
                return diff
        return None
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return f"{path}: lengths {len(a)} != {len(b)}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            diff = first_difference(x, y, f"{path}[{i}]")
            if diff is not None:
                return diff
        return None
    if isinstance(a, np.ndarray | numbers.Number) and not isinstance(a, bool):
        x, y = np.asarray(a), np.asarray(b)
        if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
            return f"{path}: {a!r} != {b!r}"
        return None
    if a != b:
        return f"{path}: {a!r} != {b!r}"
    return None


def largest_difference(a: Any, b: Any, path: str = "", floor: float = 1e-9) -> tuple[float, str]:
    """The largest relative difference between two nested outputs, ``|a - b| / (max(|a|, |b|) + floor)``, and where.

    Floats are compared with that measure; integers, booleans, strings and None must be equal (an
    inequality counts as ``inf``), as must keys, lengths, shapes and dtypes.
    """
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return math.inf, f"{path} keys {sorted(set(a) ^ set(b))}"
        return max(
            (largest_difference(a[k], b[k], f"{path}.{k}" if path else k, floor) for k in a), default=(0.0, path)
        )
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return math.inf, f"{path}: lengths {len(a)} != {len(b)}"
        pairs = zip(a, b, strict=True)
        return max(
            (largest_difference(x, y, f"{path}[{i}]", floor) for i, (x, y) in enumerate(pairs)), default=(0.0, path)
        )
    if isinstance(a, np.ndarray | float | np.floating) and not isinstance(a, bool):
        x, y = np.asarray(a), np.asarray(b)
        if x.dtype != y.dtype or x.shape != y.shape:
            return math.inf, f"{path}: {x.dtype}{x.shape} != {y.dtype}{y.shape}"
        if x.dtype.kind != "f":
            return (0.0 if np.array_equal(x, y) else math.inf), path
        if x.size == 0:
            return 0.0, path
        if not np.array_equal(np.isnan(x), np.isnan(y)):
            return math.inf, f"{path}: NaN in one only"
        ok = ~np.isnan(x)
        scale = np.maximum(np.abs(x[ok]), np.abs(y[ok])) + floor
        rel = np.abs(x[ok] - y[ok]) / scale
        return (float(rel.max()) if rel.size else 0.0), path
    return (0.0 if a == b else math.inf), path
