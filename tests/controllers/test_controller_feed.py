"""Feed-shaping baselines: the slow entry on any controller, li2023 with Zhang's CMRR, the presets.

Synthetic observations only (no simulator): the feed each controller commands at a given nominal depth
and thrust, against the schedule's and the papers' own formulas.
"""

import math

import numpy as np
import pytest
from test_controllers import _obs, _plan

from drillgym.controllers import make_controller
from drillgym.controllers.feed_schedule import EntryFeedSchedule, SlowEntry
from drillgym.controllers.li2023_cmrr import Li2023CmrrController
from drillgym.controllers.registry import PRESETS
from drillgym.envs.constants import scale_action


def _feed_scale(controller, obs) -> float:
    action, _ = controller.predict(obs)
    return scale_action(np.asarray(action, dtype=float))[1]


@pytest.mark.parametrize("base", ["none", "li2023", "zhang2005:cmrr=false"])
def test_slow_entry_multiplies_the_base_feed_up_to_the_entry_depth_only(base):
    slow = make_controller(f"{base}{',' if ':' in base else ':'}entry_feed_scale=0.5,entry_depth_mm=1.25")
    plain = make_controller(base)
    assert isinstance(slow, SlowEntry)
    for c in (slow, plain):
        c.set_plan(_plan())
    for depth_mm, factor in ((-0.2, 0.5), (0.0, 0.5), (1.2, 0.5), (1.3, 1.0), (3.0, 1.0)):
        obs = _obs((0.3, -0.2, -4.0), depth_m=depth_mm * 1e-3)
        assert _feed_scale(slow, obs) == pytest.approx(factor * _feed_scale(plain, obs), rel=1e-6)


def test_slow_entry_leaves_the_lateral_correction_to_the_base():
    slow, plain = make_controller("li2023:entry_feed_scale=0.4,entry_depth_mm=2"), make_controller("li2023")
    for c in (slow, plain):
        c.set_plan(_plan())
    for k in range(30):
        obs = _obs((0.5 + 0.01 * k, -0.3, -5.0), depth_m=k * 0.1e-3)
        a_slow, _ = slow.predict(obs)
        a_plain, _ = plain.predict(obs)
        np.testing.assert_array_equal(a_slow[:3], a_plain[:3])


def test_a_schedule_that_changes_nothing_builds_the_plain_controller():
    assert not isinstance(make_controller("li2023:entry_feed_scale=1,entry_depth_mm=2"), SlowEntry)
    assert not isinstance(make_controller("li2023:entry_feed_scale=0.5,entry_depth_mm=0"), SlowEntry)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("li2023:entry_feed_scale=1.5,entry_depth_mm=1", "never speeds up"),
        ("li2023:entry_feed_scale=0.1,entry_depth_mm=1", r"\[0.25, 1\]"),
        ("li2023:entry_feed_scale=0.5,entry_depth_mm=-1", "entry_depth_mm"),
        ("li2023:entry_feed_scale=nan,entry_depth_mm=1", "entry_feed_scale"),
        ("li2023:entry_feed_scale=half", "entry_feed_scale='half'"),
    ],
)
def test_bad_schedules_are_clear_errors(spec, message):
    with pytest.raises(ValueError, match=message):
        make_controller(spec)


def test_schedule_offset_is_the_log2_of_the_multiplier_in_action_units():
    s = EntryFeedSchedule(entry_feed_scale=0.5, entry_depth_mm=1.0)
    assert s.feed_action_offset(0.5e-3) == pytest.approx(math.log2(0.5) / 2)
    assert s.feed_action_offset(1.0e-3) == 0.0


def test_the_slow_entry_preset_is_li2023_with_a_schedule_and_takes_overrides():
    c = make_controller("li2023_slow_entry")
    name, _, fields = PRESETS["li2023_slow_entry"].partition(":")
    assert name == "li2023" and isinstance(c, SlowEntry)
    expected = dict(item.split("=") for item in fields.split(","))
    assert c.schedule.entry_feed_scale == float(expected["entry_feed_scale"])
    assert c.schedule.entry_depth_mm == float(expected["entry_depth_mm"])
    tuned = make_controller("li2023_slow_entry:entry_depth_mm=0.5,kp=1")
    assert tuned.schedule.entry_depth_mm == 0.5 and tuned.config.kp == 1.0
    desc = c.describe()
    assert desc["name"] == "li2023" and desc["config"]["entry_depth_mm"] == float(expected["entry_depth_mm"])


def test_the_tuned_preset_is_the_best_classical_baseline_with_its_y_gain():
    from drillgym.controllers.registry import BEST_CLASSICAL

    assert BEST_CLASSICAL in PRESETS
    c = make_controller(BEST_CLASSICAL)
    fields = dict(item.split("=") for item in PRESETS[BEST_CLASSICAL].partition(":")[2].split(","))
    assert isinstance(c, SlowEntry) and c.config.y_gain == float(fields["y_gain"]) != 1.0
    assert c.config.kp == float(fields["kp"]) and c.schedule.entry_depth_mm == float(fields["entry_depth_mm"])


def test_li2023_cmrr_takes_li2023s_correction_and_zhangs_feed():
    combo = make_controller("li2023_cmrr")
    li, zhang = make_controller("li2023"), make_controller("zhang2005:deformation=false")
    assert isinstance(combo, Li2023CmrrController)
    for c in (combo, li, zhang):
        c.set_plan(_plan())
    for k in range(40):
        obs = _obs((0.4, -0.1, -2.0 - 0.2 * k), depth_m=k * 0.2e-3)
        a, _ = combo.predict(obs)
        np.testing.assert_array_equal(a[:3], li.predict(obs)[0][:3])
        assert a[3] == zhang.predict(obs)[0][3]


def test_a_cmrr_capped_at_the_nominal_feed_only_ever_slows():
    capped = make_controller("li2023_cmrr:feed_scale_max=1")
    free = make_controller("li2023_cmrr")
    for c in (capped, free):
        c.set_plan(_plan())
    low_thrust = _obs((0.0, 0.0, -1.0), depth_m=3e-3)  # far below the 8 N reference: the PI speeds up
    for _ in range(40):
        capped_scale, free_scale = _feed_scale(capped, low_thrust), _feed_scale(free, low_thrust)
    assert capped_scale == pytest.approx(1.0) and free_scale > 1.5
    high_thrust = _obs((0.0, 0.0, -20.0), depth_m=3e-3)
    for _ in range(40):
        capped_scale = _feed_scale(capped, high_thrust)
    assert capped_scale < 1.0


@pytest.mark.parametrize("per_episode", [False, True])
def test_compiled_entry_feed_is_the_numpy_expression_bit_for_bit(per_episode):
    from drillgym.controllers.feed_schedule import add_entry_feed

    rng = np.random.default_rng(3)
    n = 200
    actions = rng.uniform(-1.2, 1.2, (n, 4)).astype(np.float32)
    actions[:3, 3] = [1.0, -1.0, 0.0]
    depth = rng.uniform(-1e-3, 3e-3, n).astype(np.float32)
    entry_m = rng.uniform(0.0, 2e-3, n) if per_episode else np.array([1.5e-3])
    offset = rng.uniform(-1.0, 0.0, n) if per_episode else np.array([-0.35])
    want = actions.copy()
    where = np.where(depth.astype(float) < entry_m, offset, 0.0)
    want[:, 3] = np.clip(want[:, 3] + where.astype(np.float32), -1.0, 1.0)
    got = actions.copy()
    add_entry_feed(got, depth, entry_m, offset)
    assert got.dtype == np.float32
    assert np.array_equal(got, want)
