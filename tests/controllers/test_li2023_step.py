"""li2023's compiled per-step arithmetic (controllers/li2023_step.py) against the numpy expressions, bit for bit."""

import numpy as np
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.batch import matvec, unscale_actions
from drillgym.controllers.li2023 import Li2023Controller
from drillgym.controllers.li2023_step import actions_into
from drillgym.envs.drill_env import UR5BoneDrillEnv


def _plan(**scenario):
    env = UR5BoneDrillEnv(pybullet_world=False, **scenario)
    env.reset(seed=0)
    plan = env.plan
    env.close()
    return plan


def _numpy_actions(c: Li2023Controller, depth: np.ndarray, online: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The numpy expressions the compiled step replaced (offline model, y gain, clips, action)."""
    cfg, n = c.config, len(depth)
    offline = np.zeros((n, 3))
    if cfg.offline:  # -P (R (C F)), the model read by np.interp (or the stacked models' tested equal)
        forces = np.zeros((n, 3))
        c.offline_model.lateral_into(depth, forces)
        offline = -matvec(c.lateral, matvec(c.R, matvec(c.C_tool, forces)))
    total = offline + online
    if c._y_any:
        y_base = c.R[..., :, 1]
        along = total[:, 0] * y_base[..., 0] + total[:, 1] * y_base[..., 1] + total[:, 2] * y_base[..., 2]
        adjusted = total + ((c.y_gain - 1.0) * along)[:, None] * y_base
        total = adjusted if c._y_all else np.where((c.y_gain != 1.0)[:, None], adjusted, total)
    total = np.minimum(np.maximum(total, -cfg.max_correction_m), cfg.max_correction_m)
    return total, unscale_actions(total)


def _compiled_actions(c: Li2023Controller, depth: np.ndarray, online: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    m, total, out = c._model_rows, np.empty((len(depth), 3)), np.empty((len(depth), 4), dtype=np.float32)
    rows = [x[None] if x.ndim == 2 else x for x in (c.lateral, c.R, c.C_tool)]
    actions_into(
        depth, c.config.offline, m.depth_m, m.lateral_task_n, m.sizes, m.model_of, *rows, online, c.y_gain,
        c._y_any, c._y_all, c.config.max_correction_m, total, out,
    )  # fmt: skip
    return total, out


def _assert_same(got: tuple[np.ndarray, np.ndarray], want: tuple[np.ndarray, np.ndarray]) -> None:
    """The corrections (float64: the sums' order shows) and the float32 actions, bit for bit."""
    for g, w in zip(got, want, strict=True):
        assert g.dtype == w.dtype
        assert np.array_equal(g, w, equal_nan=True)
        assert np.array_equal(np.signbit(g), np.signbit(w))


def _inputs(c: Li2023Controller, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    grid = c._model_rows.depth_m[0, : c._model_rows.sizes[0]]
    depth = np.concatenate([rng.uniform(grid[0] - 1e-3, grid[-1] + 1e-3, n - 4), grid[[0, 5, -1]], [np.nan]])
    online = rng.normal(0.0, 2e-4, (n, 3))
    online[rng.integers(0, n, 3)] = 0.0  # a robot at rest
    online[0] = [5e-3, -5e-3, 0.0]  # past the clip
    return depth.astype(np.float32).astype(float), online


@pytest.mark.parametrize(
    "spec",
    ["li2023", "li2023_tuned", "li2023:y_gain=0.8,axes=x", "li2023:offline=false", "li2023:max_correction_m=1e-4"],
)
def test_one_plans_actions_are_the_numpy_expressions_bit_for_bit(spec):
    c = make_controller(spec)
    c = getattr(c, "base", c)  # a slow entry's li2023
    c.set_plan(_plan(), num_episodes=40)
    rng = np.random.default_rng(0)
    for _ in range(20):
        depth, online = _inputs(c, 40, rng)
        _assert_same(_compiled_actions(c, depth, online), _numpy_actions(c, depth, online))


def test_stacked_episodes_with_their_own_plans_and_gains_are_the_numpy_expressions_bit_for_bit():
    parts = []
    for spec, scenario in [
        ("li2023", {}),
        ("li2023:y_gain=1.6,kp=2.5", {"beta_deg": 10.0}),
        ("li2023:y_gain=0.8", {"stickout_mm": 45.0, "beta_deg": -20.0}),
        ("li2023", {"bone": "porcine_femur"}),
    ]:
        c = make_controller(spec)
        c.set_plan(_plan(**scenario))
        parts.append(c)
    stacked = Li2023Controller.stack(parts)
    rng = np.random.default_rng(1)
    for _ in range(20):
        depth, online = _inputs(stacked, 4, rng)
        _assert_same(_compiled_actions(stacked, depth, online), _numpy_actions(stacked, depth, online))


@pytest.mark.parametrize("per_episode", [False, True])
def test_any_matrices_and_gains_give_the_numpy_expressions_bit_for_bit(per_episode):
    """The shipped plans' rotations are axis permutations (many exact zeros); random ones test the sums' order."""
    rng = np.random.default_rng(2)
    c = make_controller("li2023")
    c.set_plan(_plan(), num_episodes=30)
    shape = (30, 3, 3) if per_episode else (3, 3)
    c.R, c.lateral, c.C_tool = rng.normal(size=shape), rng.normal(size=shape), rng.normal(0.0, 1e-3, shape)
    c._gains(c.kp, c.ki, c.kd, rng.uniform(0.5, 1.5, 30) if per_episode else np.array([1.3]))
    if per_episode:
        c.y_gain[::3] = 1.0  # some episodes without the y gain
        c._y_all = False
    for _ in range(10):
        depth, online = _inputs(c, 30, rng)
        _assert_same(_compiled_actions(c, depth, online), _numpy_actions(c, depth, online))
