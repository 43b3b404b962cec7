"""The fast env step against a frozen copy of the original one (tests/envs/reference_step.py), to rounding.

Two envs with the same seed: one stepped by ``env.step``, its twin by ``reference_step``; every
observation, reward, flag and info entry, and the recorded channels, must agree within ``TOLERANCE``
(integers, flags and strings exactly), for zero and
random actions, the classical controllers (a feed schedule too), other scenarios, a force-limit stop
and every candidate effect of the diagnosis.
"""

import gymnasium as gym
import numpy as np
import pytest
from bitwise import first_difference, largest_difference
from reference_step import reference_info, reference_observation, reference_step

from drillgym import envs
from drillgym.controllers import make_controller
from drillgym.envs.effects.registry import EFFECTS

ENV_ID = envs.ENV_IDS[0]
TOLERANCE = 1e-6
"""Largest relative difference allowed, ``|a - b| / (max(|a|, |b|) + 1e-9)``: the compiled kinematics round
differently from Pinocchio's (1e-16 per call); over an episode the records differ by 1e-12 to 1e-7."""


def _mid_values(name: str) -> dict[str, float]:
    """Every parameter of an effect half-way between its off value and the top of its range."""
    return {p.name: 0.5 * (p.default + p.high) for p in EFFECTS[name].params}


def _run_pair(kwargs: dict, seed: int, policy: str | None, actions_seed: int | None, effects=None) -> int:
    """Step both envs to the end; assert records equal within ``TOLERANCE``; return the number of steps."""
    fast, ref = gym.make(ENV_ID, **kwargs), gym.make(ENV_ID, **kwargs)
    try:
        options = {"effects": effects()} if effects else None
        obs_f, info_f = fast.reset(seed=seed, options=options)
        options = {"effects": effects()} if effects else None
        obs_r, _ = ref.reset(seed=seed, options=options)
        u = ref.unwrapped
        assert largest_difference((obs_f, info_f), (reference_observation(u), reference_info(u)))[0] <= TOLERANCE
        controllers = [make_controller(policy) for _ in range(2)] if policy else None
        if controllers:
            for c, e in zip(controllers, (fast, ref), strict=True):
                c.set_plan(e.unwrapped.plan)
        rng = np.random.default_rng(actions_seed) if actions_seed is not None else None
        for k in range(4000):
            if controllers:
                start = np.array([k == 0])
                a_f, _ = controllers[0].predict(obs_f, episode_start=start)
                a_r, _ = controllers[1].predict(obs_r, episode_start=start)
            elif rng is not None:
                a_f = a_r = rng.uniform(-1.0, 1.0, 4).astype(np.float32)
            else:
                a_f = a_r = np.zeros(4, np.float32)
            out_f = fast.step(a_f)
            out_r = reference_step(u, a_r)
            worst, where = largest_difference(out_f, out_r)
            assert worst <= TOLERANCE, f"step {k}: {where} differs by {worst:.2e}"
            obs_f, obs_r = out_f[0], out_r[0]
            if out_f[2] or out_f[3]:
                break
        rec_f, rec_r = fast.unwrapped.recorder.channels(), u.recorder.channels()
        worst, where = largest_difference(
            {k: np.asarray(v) for k, v in rec_f.items()}, {k: np.asarray(v) for k, v in rec_r.items()}
        )
        assert worst <= TOLERANCE, f"recorder: {where} differs by {worst:.2e}"
        return k + 1
    finally:
        fast.close()
        ref.close()


@pytest.mark.parametrize(
    ("kwargs", "seed", "policy", "actions_seed"),
    [
        ({}, 0, None, None),
        ({}, 3, None, 5),
        ({}, 1, "li2023", None),
        ({}, 2, "zhang2005", None),
        ({}, 4, "li2023_slow_entry", None),
        ({"beta_deg": 10.0, "feed_mm_s": 1.2}, 0, "li2023", None),
        ({"cortical_thickness_mm": 1.5, "tracker": False, "ft_noise_n": 0.0}, 1, None, 9),
        ({"beta_deg": 0.0, "tracker_noise_mm": 0.0}, 2, "zhang2005", None),
    ],
)
def test_fast_step_matches_the_original_step_to_rounding(kwargs, seed, policy, actions_seed):
    assert _run_pair(kwargs, seed, policy, actions_seed) > 100


def test_fast_step_stops_at_the_force_limit_like_the_original_step():
    assert _run_pair({"force_limit_n": 4.0}, 0, None, None) < 200


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_fast_step_matches_the_original_step_to_rounding_with_each_effect(name):
    def effects():
        return [EFFECTS[name](**_mid_values(name))]

    assert _run_pair({}, 6, "li2023", None, effects) > 200


@pytest.mark.parametrize("name", ["latency", "joint_friction", "ft_drift", "ft_gain"])
def test_advance_records_what_step_records(name):
    """``advance`` (the replays' step without observation, reward and info) leaves the same recorder, cell and metrics."""
    rng = np.random.default_rng(4)
    actions = rng.uniform(-1.0, 1.0, (400, 4)).astype(np.float32)
    envs_ = [gym.make(ENV_ID).unwrapped for _ in range(2)]
    try:
        for e in envs_:
            e.reset(seed=3, options={"effects": [EFFECTS[name](**_mid_values(name))]})
        stepper, advancer = envs_
        for k, a in enumerate(actions):
            _, _, term_s, trunc_s, _ = stepper.step(a)
            assert (term_s, trunc_s) == advancer.advance(a)
            assert first_difference(stepper.cell.q_motor_rad, advancer.cell.q_motor_rad) is None, f"step {k}"
            assert first_difference(stepper.tracker_reading, advancer.tracker_reading) is None, f"step {k}"
            if term_s or trunc_s:
                break
        assert k > 100
        rec_s, rec_a = stepper.recorder.channels(), advancer.recorder.channels()
        assert (
            first_difference({k: np.asarray(v) for k, v in rec_s.items()}, {k: np.asarray(v) for k, v in rec_a.items()})
            is None
        )
        assert stepper.metrics == advancer.metrics
        with pytest.raises(RuntimeError, match="advance"):
            advancer.advance(actions[0])
    finally:
        for e in envs_:
            e.close()
