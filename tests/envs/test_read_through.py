"""On the compiled step the env's objects read their fields from the episode's state (``envs/read_through.py``).

Whoever holds the env's cell, path or tip balance sees, after every step, what the Python step would have left in
them (within the compiled step's rounding), without the step copying anything back; at the next ``reset`` the
fields are the objects' own again.
"""

import gymnasium as gym
import numpy as np
import pytest
from test_step_kernel import TOLERANCE, _random_actions

from drillgym import envs
from drillgym.envs.read_through import ReadThrough, attach, detach, forget


def _fields(env) -> dict:
    """What a reader of the env's objects sees (through references taken before the episode ran)."""
    cell, path, solver = env.cell, env.path, env.cell.solver
    return {
        "t_s": env.t_s,
        "steps": env.steps,
        "feed_scale": env.feed_scale,
        "correction_base_m": env.correction_base_m,
        "pending": [(t, *corr, scale) for t, corr, scale in env.pending],
        "rtde_tcp_base": env.rtde_tcp_base,
        "ft_mean": env.ft_mean,
        "tracker_reading": env.tracker_reading,
        "tracker_lateral_m": env.tracker_lateral_m,
        "failure": env.failure,
        "s_m": path.s_m,
        "phase": int(path.phase),
        "q_motor_rad": cell.q_motor_rad,
        "C_total": cell.C_total,
        "tip": cell.sample.tip,
        "stage": cell.sample.stage,
        "rigid": solver.rigid,
        "touching": solver.touching,
        "force": solver.force,
        "q_actual_rad": cell.q_actual_rad(),
        "marker_base_m": cell.marker_base_m(),
    }


def _assert_close(a: dict, b: dict, where: str) -> None:
    for key, value in a.items():
        if isinstance(value, (str, type(None), bool, int)) and not isinstance(value, float):
            assert value == b[key], f"{where}: {key}"
        else:
            x, y = np.asarray(value, dtype=float), np.asarray(b[key], dtype=float)
            assert x.shape == y.shape, f"{where}: {key}"
            assert np.allclose(x, y, rtol=TOLERANCE, atol=1e-15), f"{where}: {key} {x} != {y}"


@pytest.mark.parametrize("read_every", [1, 7])
def test_held_objects_show_what_the_python_step_leaves(read_every: int) -> None:
    """References to the cell, path and tip balance taken before the episode stay current on the compiled step."""
    compiled, python = gym.make(envs.ENV_IDS[0]), gym.make(envs.ENV_IDS[0])
    python.unwrapped.use_compiled_step = False
    compiled.reset(seed=3)
    python.reset(seed=3)
    c, p = compiled.unwrapped, python.unwrapped
    held = (c.cell, c.path, c.cell.solver)
    actions = _random_actions(5)
    for k in range(400):
        out = compiled.step(actions[k])
        python.step(actions[k])
        if k % read_every == 0 or out[2] or out[3]:
            assert (c.cell, c.path, c.cell.solver) == held
            _assert_close(_fields(c), _fields(p), f"step {k}")
        if out[2] or out[3]:
            break
    compiled.close()
    python.close()


def test_fields_are_the_objects_own_again_after_reset() -> None:
    """``reset`` puts every field back: the objects hold them, and the fresh episode starts as a new env's."""
    env = gym.make(envs.ENV_IDS[0])
    env.reset(seed=1)
    for _ in range(30):
        env.step(np.zeros(4, np.float32))
    u = env.unwrapped
    assert "q_motor_rad" not in vars(u.cell)  # read through the state mid-episode
    env.reset(seed=2)
    for obj in (u, u.path, u.cell, u.cell.solver):
        assert "_state_reader" not in vars(obj)
    assert "q_motor_rad" in vars(u.cell) and "t_s" in vars(u)
    fresh = gym.make(envs.ENV_IDS[0])
    fresh.reset(seed=2)
    _assert_close(_fields(u), _fields(fresh.unwrapped), "after reset")
    env.close()
    fresh.close()


class _Held(ReadThrough):
    def __init__(self) -> None:
        self.kept = "own"


def test_read_through_reads_once_per_step_and_a_write_wins() -> None:
    """A field is read from the state at the first read after a step; one written since keeps its value."""
    state = {"x": 1.0, "y": 2.0}
    reads = []

    def reader() -> dict:
        reads.append(1)
        return dict(state)

    obj = _Held()
    obj.x = 0.0
    attach(obj, reader)
    reads.clear()
    assert (obj.x, obj.y, obj.kept) == (1.0, 2.0, "own")
    assert len(reads) == 1  # both fields came with the first read
    state["x"] = 5.0
    forget(obj)  # a step ran
    obj.y = -1.0  # written after the step: wins over the state
    assert (obj.x, obj.y) == (5.0, -1.0)
    with pytest.raises(AttributeError):
        _ = obj.missing
    state["x"] = 9.0
    forget(obj)
    detach(obj)
    assert vars(obj)["x"] == 9.0 and "_state_reader" not in vars(obj)
    with pytest.raises(AttributeError):
        _ = obj.missing


@pytest.mark.parametrize("how", ["deepcopy", "pickle"])
def test_a_copy_taken_mid_episode_goes_on_as_the_original_and_apart_from_it(how: str) -> None:
    """A deep copy or a pickled env continues the episode exactly as the original does, each on its own state."""
    import copy
    import pickle

    from drillgym.envs.drill_env import UR5BoneDrillEnv

    env = UR5BoneDrillEnv(pybullet_world=False)
    env.reset(seed=5)
    actions = _random_actions(2)
    for k in range(40):
        env.step(actions[k])
    held_cell = copy.deepcopy(env.cell)  # a snapshot, not a view of the live episode
    q_then = env.cell.q_motor_rad.copy()
    twin = copy.deepcopy(env) if how == "deepcopy" else pickle.loads(pickle.dumps(env))
    for k in range(40, 4000):
        out, out_twin = env.step(actions[k]), twin.step(actions[k])
        for key in out[0]:
            assert np.array_equal(out[0][key], out_twin[0][key]), (k, key)
        assert out[1:4] == out_twin[1:4], k
        if out[2] or out[3]:
            break
    assert out[4]["metrics"] == out_twin[4]["metrics"]
    _assert_close(_fields(env), _fields(twin), "after the episode")
    assert np.array_equal(held_cell.q_motor_rad, q_then) and not np.array_equal(env.cell.q_motor_rad, q_then)
