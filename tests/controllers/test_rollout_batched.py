"""``run_episodes`` (the batched engine) against ``run_episode`` (the single env): the same rows, bit for bit.

The batched env steps every episode in one compiled call and each policy copy sees its episode's slice of the
batched observation; nothing may differ from running the seeds one after another on the single env, not even in
the last bit (the benchmark's ``episodes.csv`` and logs are compared across engines).
"""

import gymnasium as gym
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.none import NoCompensation
from drillgym.controllers.rollout import run_episode, run_episodes
from drillgym.envs import SIM_ENV_ID
from drillgym.envs.effects import build_effects
from drillgym.envs.effects.cells import CELLS
from drillgym.envs.errors import UserError


def _single_rows(spec: str, seeds: list[int], kwargs: dict, effects: str) -> list[dict]:
    env = gym.make(SIM_ENV_ID, **kwargs)
    env.unwrapped.set_effects(build_effects(effects) if effects else None)
    controller = make_controller(spec)
    try:
        return [run_episode(env, controller, s, keep_trace=False).row() for s in seeds]
    finally:
        env.close()


def _same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(
        x == y or (x != x and y != y) for x, y in zip(a.values(), b.values(), strict=True)
    )


@pytest.mark.parametrize(
    ("spec", "kwargs", "cell"),
    [
        ("li2023", {}, ""),
        ("zhang2005", {"feed_mm_s": 1.0}, ""),  # changes the feed in mid-episode: the feed scale's power
        ("li2023_tuned", {"beta_deg": -15.0}, "li2023-lab"),  # a compiled effect (joint friction)
    ],
)
def test_batched_episodes_give_the_single_envs_rows_bit_for_bit(spec, kwargs, cell):
    seeds = [4, 0, 9]
    effects = CELLS[cell] if cell else ""
    single = _single_rows(spec, seeds, kwargs, effects)
    batched = run_episodes(lambda: make_controller(spec), seeds, kwargs, effects)
    assert [r.seed for r in batched] == seeds
    for s, b in zip(single, batched, strict=True):
        assert _same(s, b.row()), {k: (s[k], b.row()[k]) for k in s if s[k] != b.row()[k]}
        assert b.steps == len(b.rewards) > 100


def test_the_step_hook_sees_every_running_episode_once_per_step_and_each_end_once():
    seen: dict[int, list[int]] = {0: [], 1: []}
    ends: list[tuple[int, int]] = []

    def hook(batch, step, actions, obs, running, ended):
        assert actions.shape == (2, 4) and obs["q_rad"].shape == (2, 6)
        for i in running:
            seen[i].append(step)
            if ended[i]:
                ends.append((i, step))

    results = run_episodes(lambda: make_controller("none"), [0, 1], {"feed_mm_s": 1.0}, on_step=hook)
    for i, r in enumerate(results):
        assert seen[i] == list(range(r.steps))
    assert sorted(ends) == [(0, results[0].steps - 1), (1, results[1].steps - 1)]


def test_a_cell_the_compiled_step_does_not_run_is_refused_with_a_clear_error():
    with pytest.raises(UserError, match="compiled step"):
        run_episodes(lambda: make_controller("none"), [0], {}, "servo_deadband:band_m=1e-4")


@pytest.mark.parametrize(("spec", "copies"), [("li2023_tuned", 1), ("none", 1), ("zhang2005", 1), ("residual_free", 3)])
def test_a_batchable_controller_steps_every_episode_as_one_copy(spec, copies):
    made = []

    def make():
        made.append(_OneAtATime() if spec == "residual_free" else make_controller(spec))
        return made[-1]

    run_episodes(make, [0, 1, 2])
    assert len(made) == copies


class _OneAtATime(NoCompensation):
    """A controller that does not declare a batch form: one copy per episode."""

    batchable = False
