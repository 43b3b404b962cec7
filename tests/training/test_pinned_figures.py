"""The shipped schedule policy and ``li2023_tuned`` pinned to their published paper-scenario figures.

The figures (README *Results*; docs/training.md, *Judged by the protocol*; docs/controllers.md, ``li2023_tuned``)
are means over the 20 judge seeds 0-19 of the paper scenario (the env defaults), each controller on the same
specimens (paired), run as ``drillgym bench`` runs them (:func:`drillgym.controllers.rollout.run_episode`). This
test replays exactly those 40 episodes (≈ 0.15-0.35 s each).

**Why the tolerances are the documents' rounding and nothing more.** An episode is a deterministic function of
its seed (``tests/envs/test_env_determinism.py``: bit-identical replays), so a replay of the same 20 seeds
reproduces the published means exactly; the only slack a test needs is the rounding of the published figure:
half a unit of its last printed digit (0.0329 mm → ± 0.00005 mm, 0.942 N → ± 0.0005 N, +14 % → ± 0.5 %).
Float differences between platforms (BLAS, libm, numba's LLVM) perturb an episode at the 1e-12 level, orders
below these bounds. A statistical tolerance derived from the seed-to-seed spread would be useless here:
measured over these 20 seeds (this test's fixture), one episode's mean deviation has SD 0.0106 mm (policy) and
0.0122 mm (``li2023_tuned``) and the paired difference SD 0.0062 mm, so a ± 2 SE band on a 20-seed mean is
± 0.005 mm for one controller and ± 0.003 mm for the difference: as wide as the claimed gain itself
(−0.0043 mm), which a pin must catch. By contrast a change anywhere in the simulator, the base controller or
the policy file moves some of the 40 episodes and, in practice, the 4-digit means: measured on
``li2023_tuned``, KP 3 → 3.03 (+1 %) moves its mean by +0.00007 mm, KI 0.25 → 0.26 by +0.00011 mm and the y gain
1.3 → 1.31 by −0.00023 mm, each outside the ± 0.00005 mm of the published 0.0372 mm.

Measured when written (this machine): policy 0.032879 mm, ``li2023_tuned`` 0.037194 mm [0.031496, 0.042892]
(t interval), 0.941846 N, 15.04 s; paired Δ −0.004315 [−0.007223, −0.001407] mm, Δ force +0.013478
[−0.001842, +0.028798] N, drill time +13.83 %.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

import drillgym.training  # noqa: F401  (registers the residual:... controllers, as the drillgym command does)
from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode

JUDGE_SEEDS = range(20)
T975_DF19 = 2.0930240544083087  # Student t 97.5 % quantile, 19 degrees of freedom (tables: 2.093)
METRICS = ("deviation_mean_mm", "lateral_force_max_n", "drill_time_s")


@pytest.fixture(scope="module")
def paper_episodes() -> dict[str, dict[str, np.ndarray]]:
    """Per controller and metric, the 20 judge episodes of the paper scenario, seed order."""
    env = gym.make("drillgym/UR5BoneDrill-v1")
    try:
        out = {}
        for spec in ("li2023_tuned", "residual:shipped"):
            controller = make_controller(spec)
            results = [run_episode(env, controller, seed, keep_trace=False) for seed in JUDGE_SEEDS]
            assert not any(r.failure for r in results), spec
            out[spec] = {m: np.array([r.metrics[m] for r in results]) for m in METRICS}
        return out
    finally:
        env.close()


def _ci(x: np.ndarray) -> tuple[float, float, float]:
    half = T975_DF19 * float(np.std(x, ddof=1)) / math.sqrt(x.size)
    return float(x.mean()), float(x.mean()) - half, float(x.mean()) + half


def _published(value: float, figure: float, digits: int) -> bool:
    """``value`` prints as ``figure`` with ``digits`` decimals: within half a unit of the last digit."""
    return abs(value - figure) <= 0.5 * 10.0**-digits + 1e-12


def test_li2023_tuned_gives_its_published_paper_figures(paper_episodes):
    """docs/training.md: 0.0372 mm, 15.0 s; docs/controllers.md: 0.942 N; README: 0.037 mm, CI high 0.043 mm.

    The CI's low bound is 0.0315 mm (bench prints it as 0.031; the README and docs/controllers.md said 0.032 until
    this replay showed it): pinned to four decimals, since three would put it on the rounding edge.
    """
    tuned = paper_episodes["li2023_tuned"]
    mean, low, high = _ci(tuned["deviation_mean_mm"])
    assert _published(mean, 0.0372, 4), mean
    assert _published(high, 0.043, 3) and _published(low, 0.0315, 4), (low, high)
    assert _published(float(tuned["lateral_force_max_n"].mean()), 0.942, 3)
    assert _published(float(tuned["drill_time_s"].mean()), 15.0, 1)


def test_the_shipped_policy_gives_its_published_paper_figures_against_li2023_tuned(paper_episodes):
    """docs/training.md, seed 0 (ships): paper deviation 0.0329 mm; paired against ``li2023_tuned`` Δ deviation
    −0.004 [−0.007, −0.001] mm, Δ peak force +0.013 [−0.002, +0.029] N, drill time +14 %; README: −10 to −12 %."""
    policy, tuned = paper_episodes["residual:shipped"], paper_episodes["li2023_tuned"]
    assert _published(float(policy["deviation_mean_mm"].mean()), 0.0329, 4)
    dev = _ci(policy["deviation_mean_mm"] - tuned["deviation_mean_mm"])
    assert all(_published(v, f, 3) for v, f in zip(dev, (-0.004, -0.007, -0.001), strict=True)), dev
    force = _ci(policy["lateral_force_max_n"] - tuned["lateral_force_max_n"])
    assert all(_published(v, f, 3) for v, f in zip(force, (0.013, -0.002, 0.029), strict=True)), force
    time_pct = 100.0 * (policy["drill_time_s"].mean() / tuned["drill_time_s"].mean() - 1.0)
    assert _published(time_pct, 14.0, 0), time_pct
    gain_pct = 100.0 * (policy["deviation_mean_mm"].mean() / tuned["deviation_mean_mm"].mean() - 1.0)
    assert -12.5 <= gain_pct <= -9.5, gain_pct  # the README's "−10 to −12 %" (over the five seeds), rounded
