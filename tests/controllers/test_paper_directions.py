"""The directions of Li 2023's compensation claims in the simulated paper scenario, paired by seed.

Li §4: compensation (KP 4) brings the mean deviation from 0.703 to 0.305 mm (−57 %) and the entry-hole
offset from 0.8 to 0.2 mm; at KP 1 the deviation is 0.587 mm, so KP 4 < KP 1. Each seed runs every controller
on the same specimen and noise draw (paired), three seeds (0.1 s an episode).

What is claimed, and why these bars (measured over seeds 0-9 when this test was written):

* li2023 ≤ 0.55 × none, per seed, for the deviation and the hole offset: the 45 % reduction bar of the
  calibration's checks (``deviation_reduction_ge_45pct`` in ``drillgym.eval.calibration.calibrate``), short of
  Li's 57 %; measured ratios 0.17-0.24 (deviation) and 0.18-0.26 (offset), so the bar has > 2x margin.
* KP 1 > KP 4, per seed, for the deviation and the hole offset: a direction only. The simulated KP gap is
  0.033-0.075 mm (mean 0.048, SD 0.012 over seeds), far below Li's 0.28 mm (docs/physics.md §6-7), so only
  its sign is the claim; the smallest measured gap is ~3 SD above 0.
* No force direction: the sim's li2023 peak lateral force is not reliably below none's (seed 3: 1.45 N
  against 1.43 N; docs/physics.md §6), so Li's 1.3 → 0.7 N is not claimed here.
"""

import gymnasium as gym
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.rollout import run_episode

SEEDS = (0, 1, 2)


@pytest.fixture(scope="module")
def paired():
    env = gym.make("drillgym/UR5BoneDrill-v1")  # the env defaults are the paper scenario (β 30°, 0.5 mm/s)
    try:
        out = {}
        for spec in ("none", "li2023", "li2023:kp=1"):
            policy = None if spec == "none" else make_controller(spec)
            out[spec] = [run_episode(env, policy, seed, keep_trace=False).metrics for seed in SEEDS]
        return out
    finally:
        env.close()


@pytest.mark.parametrize("metric", ["deviation_mean_mm", "hole_offset_mm"])
def test_li2023_removes_at_least_45_percent_of_the_uncompensated_value_in_every_seed(paired, metric):
    for none, li in zip(paired["none"], paired["li2023"], strict=True):
        assert li[metric] <= 0.55 * none[metric], (metric, li[metric], none[metric])


@pytest.mark.parametrize("metric", ["deviation_mean_mm", "hole_offset_mm"])
def test_kp4_deviates_less_than_kp1_in_every_seed(paired, metric):
    for kp1, kp4 in zip(paired["li2023:kp=1"], paired["li2023"], strict=True):
        assert kp4[metric] < kp1[metric], (metric, kp4[metric], kp1[metric])
