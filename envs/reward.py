"""The drilling task's reward and action checks, shared by the simulated and the real env.

Per agent step::

    r = -w_dev · deviation_mm - w_force · lateral_force_n - w_smooth · |a - a_prev|² - w_peak · Δpeak_n

``deviation_mm`` is the step's lateral deviation (the sim's true tip; on a real cell the tracker's),
``lateral_force_n`` the step's mean lateral F/T force, and ``Δpeak_n`` how far that force raises the
episode's running maximum, so the last term sums to ``w_peak`` times the episode's peak lateral force.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numba
import numpy as np

from drillgym.envs.constants import ACTION_DIM
from drillgym.envs.errors import UserError

TERM_NAMES = ("deviation", "force", "smooth", "peak_force")
"""The reward terms, in :meth:`RewardWeights.terms`'s order (the rows of :func:`batch_rewards_into`'s ``terms``)."""


@dataclass(frozen=True)
class RewardWeights:
    """Weights of the reward terms.

    Attributes:
        deviation: per mm of lateral deviation.
        force: per N of the step's mean lateral force.
        smooth: per unit² of action change.
        peak_force: per N by which the step raises the episode's peak lateral force.
    """

    deviation: float = 1.0
    force: float = 0.1
    smooth: float = 0.01
    peak_force: float = 0.0

    def __post_init__(self) -> None:
        for name in ("deviation", "force", "smooth", "peak_force"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0.0):
                raise UserError(f"reward_{name}_weight={value!r} must be a finite number >= 0")
            object.__setattr__(self, name, float(value))

    def terms(
        self, deviation_m: Any, lateral_force_n: Any, action: np.ndarray, prev_action: np.ndarray, peak_n: Any
    ) -> dict[str, Any]:
        """The step's reward terms (``info["reward_terms"]``); ``peak_n`` is the running peak before this step (N).

        Floats for one episode; for a batch (``action`` of shape (N, 4), the others of shape (N,)), arrays
        with one entry per episode.
        """
        if action.ndim == 2:  # a batch: the batched env's compiled terms (their running peaks left as given)
            n = len(action)
            rows, reward = np.empty((4, n)), np.empty(n)
            f = np.asarray
            batch_rewards_into(
                self.vector(), f(deviation_m, float), f(lateral_force_n, float), f(action, float),
                f(prev_action, float), np.array(peak_n, dtype=float), np.ones(n, dtype=bool), rows, reward,
            )  # fmt: skip
            return dict(zip(TERM_NAMES, rows, strict=True))
        # np.sum((a - b) ** 2) in Python floats: numpy adds four terms in order
        a0, a1, a2, a3 = action.tolist()
        p0, p1, p2, p3 = prev_action.tolist()
        d0, d1, d2, d3 = a0 - p0, a1 - p1, a2 - p2, a3 - p3
        change = d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3
        rise = max(lateral_force_n - peak_n, 0.0)
        return {
            "deviation": -self.deviation * deviation_m * 1e3,
            "force": -self.force * lateral_force_n,
            "smooth": -self.smooth * change,
            "peak_force": -self.peak_force * rise,
        }

    def vector(self) -> np.ndarray:
        """The weights in :data:`TERM_NAMES`' order, as :func:`batch_rewards_into` takes them."""
        return np.array([self.deviation, self.force, self.smooth, self.peak_force])


@numba.njit(cache=True)
def batch_rewards_into(
    weights: np.ndarray,
    deviation_m: np.ndarray,
    lateral_force_n: np.ndarray,
    action: np.ndarray,
    prev_action: np.ndarray,
    peak_n: np.ndarray,
    running: np.ndarray,
    terms: np.ndarray,
    reward: np.ndarray,
) -> None:  # pragma: no cover (compiled)
    """:meth:`RewardWeights.terms` of a batch and the reward, in one call, with numpy's arithmetic term for term.

    ``(a − a_prev)²`` is summed over the row in order; ``np.maximum`` gives the peak's rise and the running peak.

    ``weights``: the four weights (deviation, force, smooth, peak force); the step's ``deviation_m`` and
    ``lateral_force_n`` (N,); ``action`` and ``prev_action`` (N, 4); ``peak_n`` (N,) the running peaks before the
    step, raised to the step's lateral force in place; ``running`` (N,) which episodes stepped. Writes ``terms``
    (4, N) and ``reward`` (N,): the four terms' sum in their order for a running episode, 0 for the others.
    """
    w_dev, w_force, w_smooth, w_peak = -weights[0], -weights[1], -weights[2], -weights[3]
    for i in range(action.shape[0]):
        d0 = action[i, 0] - prev_action[i, 0]
        d1 = action[i, 1] - prev_action[i, 1]
        d2 = action[i, 2] - prev_action[i, 2]
        d3 = action[i, 3] - prev_action[i, 3]
        change = d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3  # np.add.reduce over the row, in order
        lateral, peak = lateral_force_n[i], peak_n[i]
        rise = lateral - peak
        if not (rise >= 0.0 or rise != rise):  # np.maximum(rise, 0.0)
            rise = 0.0
        t0 = w_dev * deviation_m[i] * 1e3
        t1 = w_force * lateral
        t2 = w_smooth * change
        t3 = w_peak * rise
        terms[0, i], terms[1, i], terms[2, i], terms[3, i] = t0, t1, t2, t3
        reward[i] = t0 + t1 + t2 + t3 if running[i] else 0.0
        if not (peak >= lateral or peak != peak):  # np.maximum(peak, lateral)
            peak_n[i] = lateral


def checked_action(action: np.ndarray, consequence: str, num_envs: int | None = None) -> np.ndarray:
    """``action`` as a float array clipped to [-1, 1]; ``ValueError`` naming ``consequence`` if its shape or values are bad.

    Args:
        action: the agent's action (:data:`drillgym.envs.constants.ACTION_DIM` entries), or one per episode of a
            batch of ``num_envs`` (shape (num_envs, ACTION_DIM)).
        consequence: what the env did about a bad action, e.g. ``"env state unchanged"`` or ``"nothing sent"``.
        num_envs: None for one action; the batch size otherwise (the error then names the bad episodes).
    """
    a = np.asarray(action, dtype=float)
    shape = (ACTION_DIM,) if num_envs is None else (num_envs, ACTION_DIM)
    if a.shape != shape:
        raise UserError(f"action must have shape {shape}, got {np.shape(action)}")
    if num_envs is None:  # one action: four floats, cheaper in Python than through numpy's calls
        values = a.tolist()
        if all(map(math.isfinite, values)):  # clipped as np.clip(a, -1, 1) clips (-0.0 stays -0.0)
            return np.array([-1.0 if x < -1.0 else (1.0 if x > 1.0 else x) for x in values])
    if not np.isfinite(a).all():
        where = "" if num_envs is None else f" in episodes {np.flatnonzero(~np.isfinite(a).all(axis=1)).tolist()}"
        raise UserError(f"action={a.tolist()} contains NaN or inf{where}; rejected ({consequence})")
    return np.minimum(np.maximum(a, -1.0), 1.0)  # np.clip(a, -1, 1), without its Python wrapper
