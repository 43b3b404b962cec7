"""Models the held-out data cannot rule out against the named one are reported as alternatives."""

from __future__ import annotations

import numpy as np
from test_diagnosis_pair_rule import _score

from drillgym.eval.diagnosis.rank import alternatives

S0 = 2000.0
"""Penalised score of "no effect" in these examples."""


def _named(names, after, score, spread, seed):
    s = _score(names, 11.0, after, score)
    s.ci_low = 0.5
    s.score_draws = score + np.random.default_rng(seed).normal(0.0, spread, 500)
    return s


def test_an_effect_that_fits_about_as_well_is_not_ruled_out():
    named = _named(("tool_length",), 3.0, 300.0, 40.0, 1)
    swap = _named(("kinematic_offset",), 3.2, 320.0, 40.0, 2)  # better in some resamples
    swap_plus = _named(("kinematic_offset", "latency"), 3.2, 320.5, 40.0, 3)  # the same with nothing added
    alts = alternatives([named, swap, swap_plus], named, S0)
    assert [a["name"] for a in alts] == ["kinematic_offset"] and 0.05 <= alts[0]["p_better"] < 0.5


def test_supersets_clearly_worse_and_unnameable_models_are_not_alternatives():
    named = _named(("tool_length",), 3.0, 300.0, 10.0, 1)
    superset = _named(("tool_length", "ft_drift"), 2.9, 290.0, 10.0, 2)  # adds to the named explanation
    worse = _named(("latency",), 8.0, 800.0, 10.0, 3)  # never better
    weak = _named(("ft_drift",), 10.0, 280.0, 10.0, 4)  # scores well but removes little of the gap
    weak.shrink = 0.1
    assert alternatives([superset, named, worse, weak], named, S0) == []
