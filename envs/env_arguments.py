"""The sim env's arguments and ``reset`` options, checked before anything changes (clear errors naming the value)."""

from __future__ import annotations

import difflib
from dataclasses import fields
from typing import Any

import numpy as np

from drillgym.envs.errors import UserError
from drillgym.envs.scenario import Scenario

RESET_OPTIONS = frozenset({"scenario", "effects", "specimen_seed"})
"""Keys ``reset(options=...)`` accepts."""


ENV_ARGUMENTS = (
    "render_mode",
    "cell_params",
    "bone_material",
    "reward_deviation_weight",
    "reward_force_weight",
    "reward_smooth_weight",
    "reward_peak_force_weight",
    "render_width_px",
    "render_height_px",
    "pybullet_world",
)
"""The env's own keyword arguments, beside the scenario's (:class:`drillgym.envs.scenario.Scenario`)."""


def check_arguments(scenario_kwargs: dict[str, Any]) -> None:
    """``TypeError`` naming every accepted argument and the closest one for each unknown name."""
    known = sorted([*ENV_ARGUMENTS, *(f.name for f in fields(Scenario))])
    unknown = sorted(set(scenario_kwargs) - set(known))
    if not unknown:
        return
    hints = []
    for name in unknown:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hints.append(f"{name!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    raise TypeError(f"unknown argument(s) {', '.join(hints)}; accepted: {', '.join(known)}")


def checked_specimen_seed(value: Any) -> int | None:
    """``reset``'s ``specimen_seed`` option: None or a non-negative integer."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise UserError(f"reset(options={{'specimen_seed': {value!r}}}): a non-negative integer seed, or None")
    return int(value)
