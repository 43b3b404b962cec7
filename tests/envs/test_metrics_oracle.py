"""Li-style episode metrics (``envs/metrics.py``) against hand-computed values on hand-built recordings.

The expected numbers come from the definitions as the docs state them (Li 2023 §3.4 and
``episode_metrics``' docstring), written out here sample by sample, never from the module's own helpers:

* force filter: trailing mean of the last 20 F/T samples (0.2 s at 100 Hz), fewer at the start;
* drilling interval: from the first sample with contact (stage > 0) to the last sample of the feed, both in;
* stable stage: feed samples whose commanded depth is at least full engagement + 0.5 mm and below the target.

Every comparison is exact to float rounding (``rel=1e-12``): the recordings are built so that the
definitions, not the numerics, decide each value, and one sample more or less changes it by far more.
"""

import math
import warnings

import numpy as np
import pytest

from drillgym.envs.metrics import FORCE_FILTER_SAMPLES, METRIC_NAMES, EpisodeRecorder, episode_metrics, moving_average

EXACT = 1e-12
"""Relative tolerance of the exact checks: float rounding of sums of at most 100 terms (~1e-14)."""


def _trailing_mean(x: np.ndarray, n: int) -> np.ndarray:
    """The oracle filter: sample ``k`` is the plain mean of samples ``max(0, k-n+1) .. k``."""
    x = np.asarray(x, dtype=float)
    return np.array([x[max(0, k - n + 1) : k + 1].mean(axis=0) for k in range(len(x))])


def _recording(
    phase: list[int],
    stage: list[int],
    depth_cmd_m: list[float] | None = None,
    deviation_m: list[float] | None = None,
    force_n: np.ndarray | None = None,
    tracker_m: list[float] | None = None,
) -> EpisodeRecorder:
    n = len(phase)
    return EpisodeRecorder(
        t_s=[0.5 + 0.01 * k for k in range(n)],  # 100 Hz, not starting at 0: drill time is a difference
        phase=list(phase),
        stage=list(stage),
        depth_cmd_m=list(depth_cmd_m if depth_cmd_m is not None else [0.0] * n),
        deviation_m=list(deviation_m if deviation_m is not None else [0.0] * n),
        ft_force_n=list(force_n if force_n is not None else np.zeros((n, 3))),
        tracker_deviation_m=list(tracker_m or []),
    )


# The interval recording: 30 samples of approach (phase 0, no contact), 50 of feed (phase 1) of which the
# first 5 are in air (stage 0), then 20 of retraction (phase 2) still in the hole. Contact: samples 35..99;
# drilling interval: 35..79 (45 samples).
N = 100
PHASE = [0] * 30 + [1] * 50 + [2] * 20
STAGE = [0] * 35 + [1, 2, 3] + [4] * 62
FIRST_CONTACT, LAST_FEED = 35, 79


def _interval_recording() -> EpisodeRecorder:
    """Deviation 5 mm before contact and 9 mm after the feed; inside, 0.00, 0.01, ..., 0.44 mm."""
    dev = [5e-3] * FIRST_CONTACT + [1e-5 * i for i in range(45)] + [9e-3] * 20
    tracker = [2e-3] * FIRST_CONTACT + [1e-4] * 45 + [2e-3] * 20
    return _recording(PHASE, STAGE, deviation_m=dev, tracker_m=tracker)


def test_the_deviation_is_averaged_over_first_contact_to_the_end_of_the_feed_both_ends_in():
    """Mean of 0, 0.01, ..., 0.44 mm is 0.22 mm; max 0.44 mm. One sample before contact (5 mm) or after the
    feed (9 mm) would move the mean by > 0.1 mm and the max to 5 or 9 mm; dropping an end sample moves the
    mean by 0.005 mm, far beyond ``EXACT``."""
    m = episode_metrics(_interval_recording(), entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0)
    assert m["deviation_mean_mm"] == pytest.approx(0.22, rel=EXACT)
    assert m["deviation_max_mm"] == pytest.approx(0.44, rel=EXACT)
    assert m["tracker_deviation_mean_mm"] == pytest.approx(0.1, rel=EXACT)


def test_drill_time_runs_from_the_first_contact_sample_to_the_last_feed_sample():
    """Samples 35 and 79 at 100 Hz: 0.44 s (44 intervals), not 0.45 s (45 samples) nor 0.43 s."""
    m = episode_metrics(_interval_recording(), entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0)
    assert m["drill_time_s"] == pytest.approx(0.44, rel=1e-9)  # t_s holds 0.5 + 0.01 k: 1e-15 s rounding


def test_a_drilling_interval_ending_with_a_recording_that_has_no_feed_runs_to_the_last_sample():
    """With no sample in the feed phase, the interval ends with the recording: 35..99, 65 samples."""
    rec = _interval_recording()
    m = episode_metrics(rec, entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0, feed_phase=7)
    dev = np.asarray(rec.deviation_m)[FIRST_CONTACT:]
    assert m["deviation_mean_mm"] == pytest.approx(dev.mean() * 1e3, rel=EXACT)
    assert m["deviation_max_mm"] == pytest.approx(9.0, rel=EXACT)
    assert m["drill_time_s"] == pytest.approx(0.64, rel=1e-9)


def test_a_contact_after_the_feed_ended_is_a_one_sample_interval():
    """Contact first seen at sample 85, after the feed (30..79): the interval is that sample alone."""
    stage = [0] * 85 + [4] * 15
    dev = [0.0] * 85 + [0.3e-3] + [7e-3] * 14
    m = episode_metrics(_recording(PHASE, stage, deviation_m=dev), 1e-3, 3e-3, 0.0)
    assert m["deviation_mean_mm"] == pytest.approx(0.3, rel=EXACT)
    assert m["deviation_max_mm"] == pytest.approx(0.3, rel=EXACT)
    assert m["drill_time_s"] == 0.0


def test_no_contact_reports_only_the_hole_offset_in_mm():
    m = episode_metrics(_recording(PHASE, [0] * N), 1e-3, 3e-3, hole_offset_m=0.25e-3)
    assert set(m) == set(METRIC_NAMES)
    assert m["hole_offset_mm"] == pytest.approx(0.25, rel=EXACT)
    assert all(math.isnan(v) for k, v in m.items() if k != "hole_offset_mm")


def test_the_hole_offset_is_reported_in_mm_with_contact_too():
    m = episode_metrics(_interval_recording(), 1e-3, 3e-3, hole_offset_m=-0.8e-3)
    assert m["hole_offset_mm"] == pytest.approx(-0.8, rel=EXACT)


def test_no_tracker_channel_leaves_the_tracker_metric_nan():
    rec = _interval_recording()
    rec.tracker_deviation_m.clear()
    assert math.isnan(episode_metrics(rec, 1e-3, 3e-3, 0.0)["tracker_deviation_mean_mm"])


def test_the_moving_average_is_a_trailing_mean_with_fewer_samples_at_the_start():
    """Against the plain loop of the definition, 1-D and per column of a (k, 3) array, for 1, 3 and 20 samples."""
    rng = np.random.default_rng(0)
    x = rng.standard_normal((50, 3))
    for n in (1, 3, 20):
        np.testing.assert_allclose(moving_average(x, n), _trailing_mean(x, n), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(moving_average(x[:, 0], n), _trailing_mean(x[:, 0], n), rtol=1e-12, atol=1e-12)


def _spike_recording(k_spike: int = 40) -> EpisodeRecorder:
    """Feed with contact throughout; a single F/T sample of (12, 16, -40) N at ``k_spike`` (lateral 20 N)."""
    n = 80
    force = np.zeros((n, 3))
    force[k_spike] = [12.0, 16.0, -40.0]
    depth = [2e-3 if 20 <= k < 40 else 0.5e-3 for k in range(n)]  # stable stage: samples 20..39 only
    return _recording([1] * n, [4] * n, depth_cmd_m=depth, force_n=force)


def test_the_force_filter_is_li_s_twenty_samples():
    """Li 2023 §3.4: a 20-sample moving average. One 20 N lateral / 40 N thrust sample reads 1 N / 2 N
    filtered (a 19- or 21-sample filter gives 1.053 or 0.952 N); lateral is the magnitude of (Fx, Fy)."""
    assert FORCE_FILTER_SAMPLES == 20
    m = episode_metrics(_spike_recording(), entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0)
    assert m["lateral_force_max_n"] == pytest.approx(1.0, rel=EXACT)
    assert m["thrust_max_n"] == pytest.approx(2.0, rel=EXACT)


def test_the_force_filter_looks_back_only():
    """The spike at sample 40 comes after the stable stage (20..39): a trailing filter shows none of it there."""
    m = episode_metrics(_spike_recording(), entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0)
    assert m["lateral_force_stable_n"] == 0.0
    early = episode_metrics(_spike_recording(k_spike=25), entry_depth_m=1e-3, depth_m=3e-3, hole_offset_m=0.0)
    assert early["lateral_force_stable_n"] == pytest.approx(15 * 1.0 / 20, rel=EXACT)  # 25..39 of 20..39 see 1 N


def test_forces_outside_the_drilling_interval_are_not_counted_except_through_the_filter_window():
    """A 100 N thrust/lateral burst 30 samples before contact is out of the window by the time contact starts;
    one just after the feed ends is never in the interval. Inside, a steady (3, 4, -6) N: 5 N lateral, 6 N thrust."""
    force = np.zeros((N, 3))
    force[FIRST_CONTACT - 30 : FIRST_CONTACT - 20] = [60.0, 80.0, -100.0]  # samples 5..14: gone by sample 34
    force[FIRST_CONTACT:] = [3.0, 4.0, -6.0]
    force[LAST_FEED + 1] = [600.0, 800.0, -1000.0]
    m = episode_metrics(_recording(PHASE, STAGE, force_n=force), 1e-3, 3e-3, 0.0)
    assert m["lateral_force_max_n"] == pytest.approx(5.0, rel=EXACT)
    assert m["thrust_max_n"] == pytest.approx(6.0, rel=EXACT)


# Stable-stage recording: full engagement at 1 mm, so the stable stage starts at 1.5 mm; target depth 3 mm.
ENTRY_M, DEPTH_M = 1.0e-3, 3.0e-3
STABLE_START_M = ENTRY_M + 0.5e-3
"""Stated in ``envs/metrics.py`` and docs/physics.md: 0.5 mm past full engagement (written out, not imported)."""
NUDGE_M = 1e-9
"""1 nm: 'just outside / inside' a boundary, far below any depth that matters and far above float rounding
of millimetre depths (~1e-19 m)."""


def _stable_recording() -> tuple[EpisodeRecorder, list[int]]:
    """60 feed samples in contact; lateral force ``k`` N at sample ``k`` (as 0.6k, 0.8k), so every sample's
    filtered force differs and adding or dropping one changes the stable-stage mean. Returns the recording and
    the samples that the definition puts in the stable stage."""
    n = 60
    depth = [ENTRY_M] * 25  # 0..24: engaged, not yet 0.5 mm past it
    depth += [STABLE_START_M - NUDGE_M]  # 25: just short of the stable stage
    depth += [STABLE_START_M]  # 26: exactly at its start: in
    depth += [2e-3] * 14  # 27..40: in
    depth += [DEPTH_M - NUDGE_M]  # 41: just short of the target: in
    depth += [DEPTH_M]  # 42: at the target: out
    depth += [3.5e-3] * (n - 43)  # 43..59: past it: out
    phase = [1] * n
    phase[30] = 2  # a sample in the depth range but not feeding: out
    k = np.arange(n, dtype=float)
    force = np.stack([0.6 * k, 0.8 * k, -np.ones(n)], axis=1)
    stable = [*range(26, 30), *range(31, 42)]
    return _recording(phase, [4] * n, depth_cmd_m=depth, force_n=force), stable


def test_the_stable_stage_starts_half_a_millimetre_past_full_engagement_and_ends_before_the_target():
    """Mean filtered lateral force over exactly samples 26..29 and 31..41 (see :func:`_stable_recording`)."""
    rec, stable = _stable_recording()
    lateral = _trailing_mean(np.arange(60, dtype=float), 20)  # filtered |(0.6k, 0.8k)| = filtered k
    expected = float(np.mean(lateral[stable]))
    m = episode_metrics(rec, entry_depth_m=ENTRY_M, depth_m=DEPTH_M, hole_offset_m=0.0)
    assert m["lateral_force_stable_n"] == pytest.approx(expected, rel=EXACT)
    for wrong in (
        [25, *stable],  # the sample 1 nm short of the start counted
        stable[1:],  # the sample exactly at the start dropped
        [*stable, 42],  # the sample at the target depth counted
        [s for s in stable if s != 41],  # the sample 1 nm short of the target dropped
        sorted([*stable, 30]),  # the non-feeding sample counted
    ):
        assert abs(float(np.mean(lateral[wrong])) - expected) > 1e-3 * expected  # each mistake is visible


def test_no_stable_sample_leaves_the_stable_force_nan():
    """Target depth at full engagement + 0.5 mm: the stable stage is empty by definition. NaN by decision, not
    by numpy's mean of nothing (which warns on every such episode of a benchmark)."""
    rec, _ = _stable_recording()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        m = episode_metrics(rec, entry_depth_m=ENTRY_M, depth_m=STABLE_START_M, hole_offset_m=0.0)
    assert math.isnan(m["lateral_force_stable_n"])
    assert math.isfinite(m["lateral_force_max_n"])
