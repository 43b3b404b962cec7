"""Many holes' offline force models read at once: each episode's depth interpolated in its own table, compiled.

A stacked li2023 (:meth:`drillgym.controllers.li2023.Li2023Controller.stack`) drills N holes, each with its own
:class:`~drillgym.controllers.models.OfflineForceModel`. Reading them one by one costs two ``np.interp`` calls per
episode per step; :class:`StackedOfflineModels` pads the tables into one array and reads every episode in one compiled
call, with ``np.interp``'s own arithmetic (its bracket search, its slope ``(f₁ − f₀) / (x₁ − x₀)`` times
``x − x₀`` plus ``f₀``, an exact grid point's value as tabulated, ``left``/``right`` of 0), so every number is
``np.interp``'s bit for bit (``tests/controllers/test_stacked_models.py``). Units: depths in m, forces in N.
"""

from __future__ import annotations

from collections.abc import Sequence

import numba
import numpy as np

from drillgym.controllers.models import OfflineForceModel
from drillgym.envs.interp_kernel import interp_one


class StackedOfflineModels:
    """The offline models of N episodes (the same model object may serve several)."""

    def __init__(self, models: Sequence[OfflineForceModel]) -> None:
        unique: dict[int, int] = {}
        tables: list[OfflineForceModel] = []
        self.model_of = np.empty(len(models), dtype=np.int64)
        for i, m in enumerate(models):
            if id(m) not in unique:
                unique[id(m)] = len(tables)
                tables.append(m)
            self.model_of[i] = unique[id(m)]
        width = max(m.depth_m.size for m in tables)
        self.depth_m = np.zeros((len(tables), width))
        self.lateral_task_n = np.zeros((len(tables), width, 2))
        self.sizes = np.array([m.depth_m.size for m in tables], dtype=np.int64)
        for k, m in enumerate(tables):
            self.depth_m[k, : m.depth_m.size] = m.depth_m
            self.lateral_task_n[k, : m.depth_m.size] = m.lateral_task_n

    def lateral_into(self, depth_m: np.ndarray, out: np.ndarray) -> None:
        """Episode i's model at ``depth_m[i]`` into ``out[i, :2]`` (N, >= 2): each row as its model's ``lateral_into``."""
        _interp_rows(self.depth_m, self.lateral_task_n, self.sizes, self.model_of, np.asarray(depth_m, float), out)


@numba.njit(cache=True)
def _interp_rows(
    xp: np.ndarray, fp: np.ndarray, sizes: np.ndarray, model_of: np.ndarray, x: np.ndarray, out: np.ndarray
) -> None:  # pragma: no cover (compiled)
    """``out[i, c] = np.interp(x[i], xp[m], fp[m, :, c], 0, 0)`` with ``m = model_of[i]``, for c in 0, 1."""
    for i in range(x.shape[0]):
        m = model_of[i]
        n = sizes[m]
        for c in range(2):
            out[i, c] = interp_one(xp[m], fp[m, :, c], n, x[i], 0.0, 0.0)
