"""Base of the reality generator's effects: the env's hook interface plus a per-episode random stream.

These effects are written apart from the candidate library (:mod:`drillgym.envs.effects`) and, where physics
allows, in another form (Stribeck friction vs Coulomb + viscous, a sigmoid layer vs a linear gradient,
jittered vs fixed latency, heat balance vs an exponential in time, ...), so that a diagnosis naming
the matching candidate has earned it. ``explains`` names the candidate that models the same physics
(None: deliberately outside the library); ``location`` is where its gap should show, for the benchmark.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from drillgym.envs.effects.base import Effect, EffectHost


class RealityEffect(Effect):
    """An effect of the reality generator."""

    explains: ClassVar[str | None] = None
    """The candidate effect (:data:`drillgym.envs.effects.EFFECTS`) that models this physics; None if none does."""
    location: ClassVar[tuple[tuple[str, ...], tuple[str, ...]] | None] = None
    """For an effect outside the library: (channels, stages) where its gap is expected."""

    def __init__(self, **values: float) -> None:
        super().__init__(**values)
        self.rng = np.random.default_rng(0)
        self.series_index, self.series_count = 0, 1
        self.tool_share: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))
        """This effect's share of the tool and marker offsets (:func:`shift_tool`)."""

    def candidate_values(self) -> dict[str, float] | None:
        """The parameters of :attr:`explains` that stand for this reality's own, where the physics equates them.

        Written from the two forms before any benchmark run (the benchmark scores parameter errors and interval
        coverage against them): the value the candidate takes in steady state, not a fit. None where the forms
        share no parameter (a sigmoid layer against a gradient, a heat balance against a work exponential).
        """
        return None

    def episode_candidate_values(self) -> dict[str, float] | None:
        """This episode's values of :attr:`explains`'s parameters, for an effect that differs per episode.

        Read after the episode (the draws are made at reset); the benchmark scores a per-episode fit against
        them. None for an effect that is the same in every episode.
        """
        return None

    def seed(self, rng: np.random.Generator) -> None:
        """Random stream of this episode (jitter, phases, states): set before the env's reset."""
        self.rng = rng

    def set_series(self, index: int, count: int) -> None:
        """This episode's place in the series: ``index`` of ``count`` holes, in drilling order.

        Set by the generator before the env's reset; read by effects that change from hole to hole.
        """
        self.series_index, self.series_count = index, count


def shift_tool(
    env: EffectHost, owner: RealityEffect, offset_task_m: np.ndarray, marker_base_m: np.ndarray | None, at_attach: bool
) -> None:
    """Set ``owner``'s share of where the physical tool (task frame, m) and the marker (base frame, m) sit.

    The cell holds the sum over the effects that move the tool (a stick-out error and joint zero errors
    add up); each call replaces ``owner``'s own share only. At attach the tip balance's starting state
    moves with the share (the tool starts where it really is); later the servo carries the tool there.
    """
    cell = env.cell
    new = np.asarray(offset_task_m, dtype=float)
    new_marker = np.zeros(3) if marker_base_m is None else np.asarray(marker_base_m, dtype=float)
    old, old_marker = (np.zeros(3), np.zeros(3)) if at_attach else owner.tool_share
    owner.tool_share = (new, new_marker)
    total = np.zeros(3) if cell.geometry_offset_task_m is None else cell.geometry_offset_task_m
    marker = np.zeros(3) if cell.marker_offset_base_m is None else cell.marker_offset_base_m
    if at_attach:
        delta = (new - old).tolist()
        s = cell.solver
        s.rigid = [a + b for a, b in zip(s.rigid, delta, strict=True)]
        s.tip = [a + b for a, b in zip(s.tip, delta, strict=True)]
        s.depth_local = s.tip[2] + s.tip[0] * s.tan_beta
        tip, rigid = s.tip, s.rigid
        cell.sample = dataclasses.replace(
            cell.sample, tip=(tip[0], tip[1], tip[2]), rigid=(rigid[0], rigid[1], rigid[2]), depth_local=s.depth_local
        )
    cell.geometry_offset_task_m = total - old + new
    if cell.marker_offset_base_m is not None or marker_base_m is not None:
        cell.marker_offset_base_m = marker - old_marker + new_marker
