"""The named episode state (envs/episode_state.py): declared fields, their record layout, and the scalar view."""

import math

import numpy as np

from drillgym.envs.episode_state import (
    PARAM_FIELDS,
    PARAMS,
    STATE,
    STATE_FIELDS,
    STATE_SCALARS,
    StateScalars,
    new_params,
    new_state,
)


def test_every_declared_field_is_in_its_record_with_its_shape_and_a_documented_meaning():
    for fields, dtype in ((STATE_FIELDS, STATE), (PARAM_FIELDS, PARAMS)):
        assert [f.name for f in fields] == list(dtype.names)
        assert len({f.name for f in fields}) == len(fields)
        for f in fields:
            assert dtype.fields[f.name][0].shape == f.shape, f.name
            assert f.doc.strip().endswith((".", ")")) and len(f.doc) > 10, f.name


def test_the_scalar_view_reads_each_scalar_field_of_an_episode_as_a_python_number():
    state = new_state(3)
    rng = np.random.default_rng(0)
    for f in STATE_FIELDS:
        state[f.name] = (
            rng.integers(0, 2, state[f.name].shape) if f.dtype != "f8" else rng.normal(size=state[f.name].shape)
        )
    v = StateScalars._make(state.view(STATE_SCALARS)[1].item())
    for name in v._fields:
        got, want = getattr(v, name), state[name][1]
        assert type(got) in (float, int, bool) and got == want, name
    assert set(v._fields) == {f.name for f in STATE_FIELDS if f.shape == ()}


def test_a_new_state_caches_no_force_rows_and_new_params_switch_every_effect_off():
    state, params = new_state(2), new_params(2)
    assert np.isnan(state["key_chip_m"]).all() and math.isnan(state[0]["key_chip_m"])
    for name in ("softening", "backlash_half_rad", "extra_latency_s", "spindle_sag_per_nm", "friction_coulomb_rad"):
        assert (params[name] == 0.0).all()
    assert not params["friction_on"].any() and not params["geometry_on"].any()


def test_each_compiled_effect_with_a_step_hook_declares_and_writes_the_parameters_its_kernel_hook_reads():
    from drillgym.envs.effects.base import _STEP_HOOKS, Effect
    from drillgym.envs.effects.registry import EFFECTS
    from drillgym.envs.episode_state import CORE_PARAM_FIELDS, CORE_STATE_FIELDS

    hooked = [
        cls
        for cls in EFFECTS.values()
        if cls.__dict__.get("compiled", False) and any(getattr(cls, h) is not getattr(Effect, h) for h in _STEP_HOOKS)
    ]
    assert {cls.name for cls in hooked} == {
        "thermal_softening",
        "joint_friction",
        "joint_backlash",
        "latency",
        "spindle_sag",
        "ft_drift",
    }
    core = {f.name for f in CORE_PARAM_FIELDS + CORE_STATE_FIELDS}
    for cls in hooked:
        assert cls.kernel_params and cls.set_kernel_params is not Effect.set_kernel_params, cls.name
        assert not {f.name for f in cls.kernel_params + cls.kernel_state} & core, cls.name  # declared once
        p = new_params(1)[0]
        cls(**{q.name: q.high for q in cls.params}).set_kernel_params(p)
        assert all(np.any(p[f.name]) for f in cls.kernel_params), cls.name  # each written, non-zero when on


def test_the_step_kernel_takes_effect_hooks_not_effect_constants():
    import ast
    import inspect

    from drillgym.envs import step_kernel

    tree = ast.parse(inspect.getsource(step_kernel))
    imported = [
        (node.module, alias.name)
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("drillgym.envs.effects")
        for alias in node.names
    ]
    assert imported and all(name.islower() for _, name in imported), imported
