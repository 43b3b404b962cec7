"""Intervals from a local design around a named fit: a one-step bootstrap on the gap's local quadratic."""

import numpy as np

from drillgym.eval.diagnosis.fit import ParamBox
from drillgym.eval.diagnosis.intervals import BOOTSTRAP, expanded_tail, parameter_intervals
from drillgym.eval.diagnosis.local_design import DESIGN_STEP, design_intervals, design_points, widest

NAMES = ("joint_friction",)  # two parameters: coulomb_rad in [0, 1e-3], viscous_s in [0, 0.02]
BOX = ParamBox(NAMES)
VALLEY = np.array([[1.0, 0.999], [0.999, 1.0]]) * 1e3
"""A valley slanted at 45° in the unit box: curvature 1998 across it, 1 along it."""


def _samples(points: list[np.ndarray], optima: np.ndarray, a: np.ndarray = VALLEY):
    """Episode k's gap is ``1 + (u − optima[k])ᵀ a (u − optima[k])`` per block (10 blocks), at each unit point."""
    n = np.full(len(optima), 10.0)
    out = []
    for u in points:
        spec = BOX.spec(u)
        uq = np.array([(v - p.low) / (p.high - p.low) for (_, p), v in zip(BOX.entries, _values(spec), strict=True)])
        d = uq[None, :] - optima
        out.append((spec, 10.0 * (1.0 + np.einsum("ki,ij,kj->k", d, a, d)), n.copy()))
    return out


def _values(spec):
    return [v for _, params in spec for _, v in params]


def test_the_design_steps_each_parameter_and_every_pair_inward_from_the_range_edges():
    inside = design_points(np.array([0.5, 0.3, 0.7]))
    assert len(inside) == 2 * 3**2 + 1
    steps = np.array(inside) - inside[0]
    assert np.allclose(np.abs(steps[1:7]).sum(axis=1), DESIGN_STEP)  # one parameter at a time
    assert np.allclose(np.abs(steps[7:]).sum(axis=1), 2 * DESIGN_STEP)  # two at a time
    edge = np.array(design_points(np.array([0.0, 1.0])))
    assert (edge >= 0.0).all() and (edge <= 1.0).all()
    assert sorted(edge[1:3, 0]) == [DESIGN_STEP, 2 * DESIGN_STEP]  # off point: stepped inward twice
    assert sorted(edge[3:5, 1]) == [1.0 - 2 * DESIGN_STEP, 1.0 - DESIGN_STEP]


def test_on_a_quadratic_valley_the_design_interval_is_the_bootstrap_of_the_episodes_optima():
    rng = np.random.default_rng(4)
    along = np.array([1.0, 1.0]) / np.sqrt(2.0)
    optima = np.array([0.4, 0.4]) + 0.05 * rng.standard_normal(6)[:, None] * along  # scattered along the valley
    centre = optima.mean(axis=0) + 0.003  # the search stopped a little off the pooled minimum
    design = [BOX.spec(u) for u in design_points(np.round(centre, 5))]
    samples = _samples(design_points(np.round(centre, 5)), optima)
    ci = design_intervals(NAMES, design, samples)
    assert ci is not None
    # Every resample's pooled gap is a quadratic with the resample's mean optimum as its minimum, which the
    # one-step bootstrap finds exactly (same resamples as the intervals', seed 0).
    idx = np.random.default_rng(0).integers(0, 6, size=(BOOTSTRAP, 6))
    means = optima[idx].mean(axis=1)
    tail = expanded_tail(6)
    for k, (_, p) in enumerate(BOX.entries):
        low, high = np.quantile(means[:, k], [tail, 1 - tail]) * (p.high - p.low) + p.low
        entry = ci["joint_friction"][p.name]
        assert abs(entry["low"] - low) < 1e-6 * (p.high - p.low) and abs(entry["high"] - high) < 1e-6 * (p.high - p.low)
        assert entry["at_search_edge"] and not entry["contains_off"]  # the valley reaches beyond the design
    # Joined with the intervals of a search that evaluated the design's lines only: the hull of the two.
    search = parameter_intervals(samples)["joint_friction"]
    joined = widest({"joint_friction": search}, ci)["joint_friction"]
    for name, entry in joined.items():
        own = ci["joint_friction"][name]
        assert entry["low"] == min(search[name]["low"], own["low"]) and entry["high"] == max(
            search[name]["high"], own["high"]
        )
        assert entry["search"] == [search[name]["low"], search[name]["high"]] and entry["design"] == [
            own["low"],
            own["high"],
        ]


def test_no_design_interval_without_a_minimum_or_with_a_failed_point():
    optima = np.full((6, 2), 0.4)
    points = design_points(np.array([0.4, 0.4]))
    design = [BOX.spec(u) for u in points]
    saddle = np.diag([1.0, -1.0]) * 1e3
    assert design_intervals(NAMES, design, _samples(points, optima, saddle)) is None
    failed = _samples(points, optima)
    failed[3] = (failed[3][0], None, None)
    assert design_intervals(NAMES, design, failed) is None
    assert widest({"joint_friction": {}}, None) == {"joint_friction": {}}
