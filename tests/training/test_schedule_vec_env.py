"""The batched schedule env (``training/schedule_vec_env.py``) against one-hole envs: the same holes and rewards.

Slot ``j`` must draw the holes worker ``j`` of a vector of :class:`ScheduleEnv` draws, and every observation,
reward and info must be theirs bit for bit, so that training on the batched engine learns from the same data.
"""

import numpy as np
import pytest
from stable_baselines3.common.vec_env import DummyVecEnv

from drillgym.envs.errors import UserError
from drillgym.training.cell import TrainingCell
from drillgym.training.config import load_config
from drillgym.training.domain_randomization import merged_ranges
from drillgym.training.env_factory import schedule_env
from drillgym.training.schedule_vec_env import ScheduleVecEnv


def _batched(cfg, n, episodes=None, workers=1):
    return ScheduleVecEnv(
        n,
        cfg.schedule_spec(),
        cfg.env_kwargs,
        merged_ranges(cfg.dr_ranges),
        cfg.paper_share,
        cfg.schedule_weights(),
        episodes=episodes,
        run_seed=cfg.seed,
        cell=cfg.training_cell(),
        workers=workers,
    )


def test_each_slot_drills_the_holes_of_its_worker_with_the_same_rewards_bit_for_bit():
    cfg = load_config("residual_schedule_sac")
    n = 3
    workers = DummyVecEnv([lambda r=r: schedule_env(cfg, rank=r) for r in range(n)])
    batched = _batched(cfg, n)
    try:
        workers.seed(5)
        batched.seed(5)
        assert np.array_equal(workers.reset(), batched.reset())
        rng = np.random.default_rng(0)
        for step in range(3):
            actions = rng.uniform(-1.0, 1.0, (n, 4)).astype(np.float32)
            if step == 1:
                actions[2] = 0.0  # the base itself: reward exactly 0
            obs_w, rew_w, done_w, info_w = workers.step(actions)
            obs_b, rew_b, done_b, info_b = batched.step(actions)
            assert np.array_equal(obs_w, obs_b)
            assert np.array_equal(rew_w, rew_b.astype(np.float32)) and done_b.all() and done_w.all()
            for a, b in zip(info_w, info_b, strict=True):
                for key in ("scenario", "episode_seed", "metrics", "base", "tuned_spec"):
                    assert a[key] == b[key], key
                assert np.array_equal(a["terminal_observation"], b["terminal_observation"])
    finally:
        workers.close()
        batched.close()


def test_fixed_holes_are_visited_once_per_reset_slot_by_slot():
    cfg = load_config("residual_schedule_sac")
    episodes = [({"beta_deg": float(b)}, 100 + k) for k, b in enumerate((0, 10, 20, 30))]
    batched = _batched(cfg, 2, episodes)
    try:
        batched.reset()
        assert [i["episode_seed"] for i in batched.reset_infos] == [100, 101]
        _, _, _, infos = batched.step(np.zeros((2, 4), dtype=np.float32))
        assert [i["episode_seed"] for i in infos] == [100, 101]
        assert [i["scenario"]["beta_deg"] for i in infos] == [0.0, 10.0]
        assert [i["episode_seed"] for i in batched.step(np.zeros((2, 4), dtype=np.float32))[3]] == [102, 103]
    finally:
        batched.close()


def test_bad_sizes_and_cells_the_compiled_step_does_not_run_are_refused():
    cfg = load_config("residual_schedule_sac")
    with pytest.raises(UserError, match="num_envs"):
        ScheduleVecEnv(0, cfg.schedule_spec())
    with pytest.raises(UserError, match="compiled step"):
        ScheduleVecEnv(2, cfg.schedule_spec(), cell=TrainingCell("servo_deadband:band_m=1e-4"))


def test_slots_drilled_in_a_worker_process_give_the_same_holes_and_rewards():
    cfg = load_config("residual_schedule_sac")
    one, two = _batched(cfg, 3), _batched(cfg, 3, workers=2)
    try:
        assert len(two.remotes) == 1
        one.seed(9)
        two.seed(9)
        assert np.array_equal(one.reset(), two.reset())
        assert one.reset_infos == two.reset_infos
        actions = np.random.default_rng(1).uniform(-1.0, 1.0, (3, 4)).astype(np.float32)
        a, b = one.step(actions), two.step(actions)
        assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
        for x, y in zip(a[3], b[3], strict=True):
            assert x.keys() == y.keys()
            assert all(np.array_equal(x[k], y[k]) if k == "terminal_observation" else x[k] == y[k] for k in x)
    finally:
        one.close()
        two.close()
    assert not two.remotes[0]._process.is_alive()


def test_an_error_in_the_worker_process_is_raised_here():
    cfg = load_config("residual_schedule_sac")
    env = _batched(cfg, 2, workers=2)
    try:
        env.reset()
        bad = np.zeros((2, 4), dtype=np.float32)
        bad[1, 2] = np.nan  # slot 1: the worker's
        with pytest.raises(ValueError, match="NaN"):
            env.step(bad)
        bad[1, 2] = 0.0
        bad[0, 0] = np.nan  # slot 0: this process's; the worker's answer is still collected
        env.reset()
        with pytest.raises(ValueError, match="NaN"):
            env.step(bad)
        env.reset()
        assert env.step(np.zeros((2, 4), dtype=np.float32))[1].tolist() == [0.0, 0.0]  # still in step
    finally:
        env.close()


@pytest.mark.parametrize(
    "cell",
    [
        {"cell": "li2023-lab"},
        {  # drawn per hole, as --cell-from-diagnosis gives: each slot runs its own hole's draw
            "cell": "joint_friction:coulomb_rad=1.5e-4,viscous_s=0.005+latency:extra_latency_s=0.01",
            "cell_ranges": {"joint_friction.coulomb_rad": [1e-4, 5e-4], "latency.extra_latency_s": [0.0, 0.08]},
        },
    ],
)
def test_a_cell_with_compiled_effects_drills_the_same_holes_batched(cell):
    """Joint friction (compiled), fixed or drawn per hole: each slot's episodes carry its hole's effects as the env's."""
    from drillgym.training.env_factory import batched_schedule, schedule_vec_env

    cfg = load_config("residual_schedule_sac", cell)
    assert batched_schedule(cfg)
    workers = DummyVecEnv([lambda r=r: schedule_env(cfg, rank=r) for r in range(2)])
    batched = schedule_vec_env(cfg, 2)
    try:
        workers.seed(3)
        batched.seed(3)
        assert np.array_equal(workers.reset(), batched.reset())
        actions = np.random.default_rng(0).uniform(-1.0, 1.0, (2, 4)).astype(np.float32)
        (_, rew_w, _, info_w), (_, rew_b, _, info_b) = workers.step(actions), batched.step(actions)
        assert np.array_equal(rew_w, np.asarray(rew_b, np.float32))
        assert [i["metrics"] for i in info_w] == [i["metrics"] for i in info_b]
        assert [i.get("cell") for i in info_w] == [i.get("cell") for i in info_b]
        if "cell_ranges" in cell:  # the holes' drawn cells differ from slot to slot and from the nominal one
            drawn = {i["cell"] for i in info_b}
            assert len(drawn) == 2 and cfg.training_cell().nominal_spec() not in drawn
    finally:
        workers.close()
        batched.close()
