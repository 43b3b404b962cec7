"""li2023-family episodes stepped in compiled code (``controllers/closed_loop``): the Python loop's numbers, bit for bit.

``run_batch`` hands a batch driven by one stacked li2023 controller (under a slow entry or not) to the compiled loop;
``compiled=False`` keeps the Python loop, a step at a time, as the reference. Everything an episode leaves is
compared: results (metrics, info, rewards), the record, the state and the noise generators after it.
"""

from collections import deque

import numpy as np
import pytest

from drillgym.controllers import make_controller
from drillgym.controllers.closed_loop import ClosedLoop, closed_loop_parts, run_closed_loop
from drillgym.controllers.li2023 import Li2023Controller
from drillgym.controllers.li2023_step import online_into
from drillgym.controllers.plan_schedule import PlanScheduledController, ScheduleSpec
from drillgym.controllers.rollout import run_batch
from drillgym.envs.batched import BatchedDrillEnv
from drillgym.envs.errors import UserError

SCENARIOS = [{"beta_deg": 20.0}, {"feed_mm_s": 0.8, "bone": "porcine_femur"}, None, {"stickout_mm": 35.0}]


def _run(spec, compiled, effects=None, scenarios=None, seeds=(3, 5, 7, 11), **env_kwargs):
    """Run one batch, return everything it leaves (results, records, state, generator states)."""
    runs = []
    real_run = ClosedLoop.run
    ClosedLoop.run = lambda self, on_end: runs.append(1) or real_run(self, on_end)  # count the compiled runs
    try:
        return _run_batch(spec, compiled, effects, scenarios, seeds, **env_kwargs)
    finally:
        ClosedLoop.run = real_run
        assert len(runs) == int(compiled)  # the compiled loop ran exactly when asked for


def _run_batch(spec, compiled, effects, scenarios, seeds, **env_kwargs):
    batch = BatchedDrillEnv(len(seeds), autoreset=False, **({"effects": effects} if effects else {}), **env_kwargs)
    try:
        policies = [_controller(s) for s in spec] if isinstance(spec, list) else (lambda: make_controller(spec))
        results = run_batch(batch, policies, list(seeds), scenarios=scenarios, compiled=compiled)
        records = [batch.record[i, : batch.recorded[i]].copy() for i in range(batch.num_envs)]
        rngs = [e.np_random.bit_generator.state for e in batch.envs]
        return results, records, batch.state.copy(), rngs
    finally:
        batch.close()


def _controller(spec):
    if spec == "schedule":
        return PlanScheduledController(ScheduleSpec(), policy=lambda _obs: np.array([0.4, -0.7, 0.2, 0.9]))
    return make_controller(spec)


def _assert_same(a, b):
    (res_a, rec_a, state_a, rng_a), (res_b, rec_b, state_b, rng_b) = a, b
    for x, y in zip(res_a, res_b, strict=True):
        assert repr(x.row()) == repr(y.row())  # NaN metrics too
        assert np.array_equal(x.rewards, y.rewards)
        assert x.rewards.dtype == y.rewards.dtype
        assert x.info.keys() == y.info.keys()
        for k in x.info:
            assert _same(x.info[k], y.info[k]), k
    for x, y in zip(rec_a, rec_b, strict=True):
        assert np.array_equal(x, y, equal_nan=True)
    assert _fields(state_a) == _fields(state_b)
    assert rng_a == rng_b


def _same(a, b):
    """Equal bit for bit: arrays by value and dtype (NaN equal to NaN), the rest by ``repr`` (a float's is exact)."""
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    return repr(a) == repr(b)


def _fields(state):
    """A state record array's fields as bytes (not its padding, which holds whatever memory held)."""
    return [state[name].tobytes() for name in state.dtype.names]


@pytest.mark.parametrize(
    ("spec", "effects", "scenarios"),
    [
        ("li2023", None, None),
        ("li2023_tuned", None, SCENARIOS),
        ("li2023:online=0", None, None),
        ("li2023:offline=0,kp=2,kd=0.5", None, None),
        ("li2023:axes=x,y_gain=0.8", "ft_drift", None),
        ("li2023_tuned", "joint_friction:coulomb_rad=4.2e-4", None),
        (["li2023_tuned", "schedule", "li2023_tuned:kp=2.5,y_gain=1.6", "schedule"], None, SCENARIOS),
    ],
)
def test_compiled_loop_gives_the_python_loops_episodes_bit_for_bit(spec, effects, scenarios):
    _assert_same(_run(spec, False, effects, scenarios), _run(spec, True, effects, scenarios))


def test_compiled_loop_keeps_the_step_limit_and_its_truncation():
    a = _run("li2023_tuned", False, max_episode_steps=150)
    b = _run("li2023_tuned", True, max_episode_steps=150)
    _assert_same(a, b)
    assert all(r.failure == "truncated" and r.steps == 150 for r in b[0])


def test_the_li2023_family_runs_compiled_and_other_policies_do_not():
    batch = BatchedDrillEnv(2, autoreset=False)
    try:
        batch.reset(seed=0)
        plan = batch.envs[0].plan
        for spec in ("li2023", "li2023_tuned", "schedule"):
            c = _controller(spec)
            c.set_plan(plan, 2)
            assert closed_loop_parts(c) is not None, spec
        zhang = make_controller("zhang2005")
        zhang.set_plan(plan)
        assert closed_loop_parts(zhang) is None
        assert closed_loop_parts(lambda obs: obs) is None
        subclass = type("Tweaked", (Li2023Controller,), {})()  # a subclass may change a step: Python steps it
        subclass.set_plan(plan, 2)
        assert closed_loop_parts(subclass) is None
    finally:
        batch.close()
    for batch in (BatchedDrillEnv(2, autoreset=False, threads=2), BatchedDrillEnv(2)):  # two threads; autoreset
        try:
            batch.reset(seed=0)
            li = make_controller("li2023")
            li.set_plan(batch.envs[0].plan, 2)
            assert not run_closed_loop(batch, li, lambda i, r: None)
        finally:
            batch.close()


def test_a_nan_action_in_the_compiled_loop_is_the_python_loops_error():
    def make():
        c = make_controller("li2023")
        c.config.y_gain = float("nan")  # past the config's check: NaN corrections from the first step
        return c

    outcomes = []
    for compiled in (False, True):
        batch = BatchedDrillEnv(2, autoreset=False)
        try:
            with pytest.raises(UserError, match="contains NaN") as err:
                run_batch(batch, make, [1, 2], compiled=compiled)
            outcomes.append((str(err.value), _fields(batch.state)))
        finally:
            batch.close()
    assert outcomes[0] == outcomes[1]


def _deque_online(points, t, period):
    """li2023's online correction as a deque of (time, correction) points gives it (the reference)."""
    while len(points) >= 2 and points[1][0] <= t:
        points.popleft()
    t0, c0 = points[0]
    if len(points) == 1 or t <= t0:
        return c0
    t1, c1 = points[1]
    t_start = t1 - period
    if t <= t_start:
        return c0
    return c0 + (c1 - c0) * (t - t_start) / (t1 - t_start)


def test_online_correction_from_the_point_ring_is_the_deques_bit_for_bit():
    rng = np.random.default_rng(4)
    li = make_controller("li2023:prediction_points=1")
    batch = BatchedDrillEnv(3, autoreset=False)
    try:
        batch.reset(seed=0)
        li.set_plan(batch.envs[0].plan, 3)
    finally:
        batch.close()
    points = deque([(0.0, np.zeros((3, 3)))])
    t, period = 0.0, 0.6
    grown = False
    for _ in range(200):
        if rng.random() < 0.4:  # queue a point, sometimes several before the time moves on (the ring grows)
            tp = t + rng.uniform(0.0, 2.0)
            c = rng.normal(size=(3, 3)) * 1e-4
            points.append((tp, c))
            li._queue_point(tp, c)
            grown = grown or li.point_times_s.size > 4
        else:
            t += rng.uniform(0.0, 0.2)
            out = np.empty((3, 3))
            online_into(li.point_times_s, li.point_corrections, li.point_ring, t, period, out)
            assert np.array_equal(out, _deque_online(points, t, period))
            assert li.point_ring[1] == len(points)
    assert grown


@pytest.mark.parametrize("draw", range(4))
def test_compiled_loop_matches_the_python_loop_on_random_configurations(draw):
    """Random gains, filters, point periods, predictions, axes, switches, slow entries, holes, cells and step limits
    (90 such draws were compared while writing the loop; four run here)."""
    rng = np.random.default_rng(100 + draw)
    fields = {
        "kp": round(float(rng.uniform(0, 6)), 3),
        "ki": round(float(rng.uniform(0, 0.6)), 3),
        "kd": round(float(rng.uniform(0, 1)), 3),
        "filter_samples": int(rng.choice([5, 10, 20, 40])),
        "point_period_s": float(rng.choice([0.05, 0.3, 0.6, 1.2])),
        "prediction_points": int(rng.integers(1, 4)),
        "axes": str(rng.choice(["x", "xy"])),
        "y_gain": round(float(rng.uniform(0, 2)), 3),
        "offline": int(rng.integers(0, 2)),
        "online": int(rng.integers(0, 2)),
        "count_executed_correction": int(rng.integers(0, 2)),
        "entry_feed_scale": round(float(rng.uniform(0.3, 1)), 3),
        "entry_depth_mm": round(float(rng.uniform(0, 3)), 3),
    }
    spec = "li2023:" + ",".join(f"{k}={v}" for k, v in fields.items())
    holes = [{"beta_deg": float(rng.uniform(-40, 40)), "feed_mm_s": float(rng.uniform(0.3, 1.5))} for _ in range(3)]
    cell = ["ft_drift", "joint_friction:coulomb_rad=3e-4", "latency:extra_latency_s=0.1", None][draw]
    limit = {"max_episode_steps": int(rng.integers(20, 300))} if draw % 2 else {}
    a = _run(spec, False, cell, holes, seeds=(1, 2, 3), **limit)
    _assert_same(a, _run(spec, True, cell, holes, seeds=(1, 2, 3), **limit))


def test_compiled_loop_grows_its_reward_rows_when_they_run_out(monkeypatch):
    """The rows for each step's rewards start at the record's step capacity; made to start at two, they grow."""
    import drillgym.controllers.closed_loop as closed_loop

    want = _run("li2023_tuned", False, seeds=(3, 5))
    monkeypatch.setattr(closed_loop, "SUBSTEPS_PER_STEP", 10**9)  # capacity // huge + 2 = 2 rows to begin with
    _assert_same(want, _run("li2023_tuned", True, seeds=(3, 5)))
