"""Bit-for-bit comparison of env outputs, for the determinism and step-equivalence tests."""

from __future__ import annotations

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
