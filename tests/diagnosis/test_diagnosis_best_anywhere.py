"""A single effect's fit is the best found anywhere: a pair holding it with the other effect switched off counts."""

from __future__ import annotations

import numpy as np

from drillgym.eval.diagnosis.context import make_spec
from drillgym.eval.diagnosis.diagnose import _best_anywhere
from drillgym.eval.diagnosis.fit import FitResult


def _fit(names, params, cal, samples=()):
    return FitResult(names=tuple(names), params=params, n_params=1, cal_objective=cal, samples=list(samples))


def test_a_single_takes_the_values_of_a_better_pair_whose_other_effect_is_switched_off():
    on = make_spec(
        ["latency", "ft_drift"],
        [{"extra_latency_s": 0.02}, {"fx_rate_n_s": 0.0, "fy_rate_n_s": 0.0, "fz_rate_n_s": 0.0}],
    )
    single = _fit(["latency"], [{"extra_latency_s": 0.01}], 5.0)
    off_pair = _fit(["latency", "ft_drift"], [dict(on[0][1]), dict(on[1][1])], 2.0, [(on, np.ones(2), np.ones(2))])
    got = _best_anywhere(single, [off_pair])
    assert got.params == [{"extra_latency_s": 0.02}] and got.cal_objective == 2.0 and got.names == ("latency",)
    assert (on[:1], 1.0, 1.0) == (got.samples[0][0], *(float(x[0]) for x in got.samples[0][1:]))
    # a pair whose other effect does something is another model: the single keeps its own fit
    drift_on = _fit(
        ["latency", "ft_drift"],
        [{"extra_latency_s": 0.02}, {"fx_rate_n_s": 0.01, "fy_rate_n_s": 0.0, "fz_rate_n_s": 0.0}],
        1.0,
    )
    assert _best_anywhere(single, [drift_on]) is single
    # and a worse pair leaves it too
    assert _best_anywhere(single, [_fit(off_pair.names, off_pair.params, 9.0)]) is single
