"""Training in a cell: effects at fixed values for evaluation, parameters drawn per training episode."""

import numpy as np
import pytest

from drillgym.controllers.plan_schedule import ScheduleSpec
from drillgym.envs.errors import UserError
from drillgym.training.cell import TrainingCell, spec_of
from drillgym.training.config import TrainConfig
from drillgym.training.env_factory import make_eval_vec_env, residual_env
from drillgym.training.schedule_env import ScheduleEnv

FRICTION = "joint_friction:coulomb_rad=0.0003"
RANGES = {"joint_friction.coulomb_rad": (0.0001, 0.0005)}


def test_a_cell_draws_its_ranged_parameters_and_keeps_the_others():
    cell = TrainingCell(FRICTION + "+latency:extra_latency_s=0.02", RANGES)
    rng = np.random.default_rng(0)
    drawn = [TrainingCell(cell.draw_spec(rng)).values for _ in range(50)]
    coulomb = np.array([d["joint_friction"]["coulomb_rad"] for d in drawn])
    assert 1e-4 <= coulomb.min() < 1.5e-4 and 4.5e-4 < coulomb.max() <= 5e-4  # uniform across the range
    assert all(d["latency"] == {"extra_latency_s": 0.02} for d in drawn)
    assert TrainingCell("li2023-lab").values == {"joint_friction": {"coulomb_rad": 0.000417}}  # a named cell


def test_the_spec_of_values_round_trips():
    values = {"joint_friction": {"coulomb_rad": 1 / 3 * 1e-3}, "latency": {"extra_latency_s": 0.0123456789}}
    assert TrainingCell(spec_of(values)).values == values


@pytest.mark.parametrize(
    ("spec", "ranges", "message"),
    [
        ("no_such_effect:x=1", {}, "no_such_effect"),
        (FRICTION, {"latency.extra_latency_s": (0.0, 0.1)}, "not in the cell"),
        (FRICTION, {"joint_friction.coulomb": (0.0, 1e-4)}, "no parameter"),
        (FRICTION, {"joint_friction.coulomb_rad": (5e-4, 1e-4)}, "ordered"),
        (FRICTION, {"joint_friction.coulomb_rad": (0.0, 1.0)}, "inside"),
    ],
)
def test_bad_cells_are_clear_errors(spec, ranges, message):
    with pytest.raises(UserError, match=message):
        TrainingCell(spec, ranges)
    with pytest.raises(UserError, match=message):
        TrainConfig(cell=spec, cell_ranges={k: list(v) for k, v in ranges.items()})


def _schedule_spec() -> ScheduleSpec:
    return TrainConfig(base="li2023_tuned", residual_mode="schedule", normalize_obs=False).schedule_spec()


def test_a_schedule_env_drills_training_holes_in_drawn_cells_and_pays_zero_for_the_base():
    cell = TrainingCell(FRICTION, RANGES)
    env = ScheduleEnv(_schedule_spec(), stream_keys=(0,), cell=cell)
    ideal = ScheduleEnv(_schedule_spec(), stream_keys=(0,))
    cells, gaps = [], []
    for k in range(3):
        env.reset(seed=4 if k == 0 else None)
        ideal.reset(seed=4 if k == 0 else None)
        assert env.scenario == ideal.scenario and env.episode_seed == ideal.episode_seed  # the cell draws are apart
        _, reward, *_, info = env.step(np.zeros(env.action_space.shape))
        _, _, *_, info_ideal = ideal.step(np.zeros(env.action_space.shape))
        assert reward == 0.0  # the base drills the same drawn cell
        cells.append(info["cell"])
        gaps.append(info["metrics"]["deviation_mean_mm"] - info_ideal["metrics"]["deviation_mean_mm"])
    assert len(set(cells)) == 3 and all(c.startswith("joint_friction:coulomb_rad=") for c in cells)
    assert max(abs(g) for g in gaps) > 1e-3  # joint friction moves the hole


def test_evaluation_runs_the_cell_at_its_own_values():
    cfg = TrainConfig(
        base="li2023_tuned",
        residual_mode="schedule",
        normalize_obs=False,
        cell=FRICTION,
        cell_ranges={k: list(v) for k, v in RANGES.items()},
    )
    venv = make_eval_vec_env(cfg)
    try:
        for _ in range(2):
            venv.reset()
            _, _, _, infos = venv.step(np.zeros((venv.num_envs, *venv.action_space.shape)))
            assert {info["cell"] for info in infos} == {FRICTION}  # never a draw
    finally:
        venv.close()


def test_a_zero_step_residual_earns_zero_against_the_base_in_the_same_drawn_cell():
    cfg = TrainConfig(
        base="li2023", paired_reward=True, cell=FRICTION, cell_ranges={k: list(v) for k, v in RANGES.items()}
    )
    env = residual_env(cfg, randomize=True)
    env.reset(seed=3)
    seen = set()
    for _ in range(2):
        _, info = env.reset()
        seen.add(info["cell"])
        while True:
            _, r, terminated, truncated, info = env.step(np.zeros(env.action_space.shape, np.float32))
            assert r == 0.0
            if terminated or truncated:
                break
    assert len(seen) == 2
