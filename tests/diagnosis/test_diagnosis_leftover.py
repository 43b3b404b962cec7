"""What a named model leaves: its held-out gap over the simulator's own level, and where that rest lies."""

from __future__ import annotations

import numpy as np

from drillgym.eval.diagnosis.channels import ALL_CHANNELS, STAGES
from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import N_CELLS, Terms
from drillgym.eval.diagnosis.rank import score_models
from drillgym.eval.diagnosis.verdict import LEFTOVER_REPORT_RATIO, summary
from drillgym.eval.diagnosis.where import locate


def _terms(level: float, hot: tuple[int, int] | None = None, extra: float = 0.0) -> Terms:
    """One episode's terms: ``level`` per term in every cell, ``extra`` more in the cell ``hot`` (stage, channel)."""
    cell_sum = np.full(N_CELLS, level)
    if hot is not None:
        cell_sum[hot] += extra
    return Terms(cell_sum, np.ones(N_CELLS), np.zeros(N_CELLS))


def test_the_leftover_ratio_is_the_gap_after_over_the_simulators_own_level():
    null = [_terms(1.0) for _ in range(4)]
    before = [_terms(10.0) for _ in range(4)]
    good = FitResult(("a",), [{}], 1, ho_terms=[_terms(1.5) for _ in range(4)])
    partial = FitResult(("b",), [{}], 1, ho_terms=[_terms(1.0, (3, 5), 800.0) for _ in range(4)])
    ratios = {s.name: s.leftover_ratio for s in score_models([good, partial], before, null)}
    assert ratios["a"] == 1.5
    assert ratios["b"] == (1.0 * N_CELLS[0] * N_CELLS[1] + 800.0) / (N_CELLS[0] * N_CELLS[1])
    cells = locate(partial.ho_terms, null)
    assert (cells[0]["stage"], cells[0]["channel"]) == (STAGES[3], ALL_CHANNELS[5]) and cells[0]["share"] == 1.0


def test_a_model_leaving_far_more_than_the_sims_level_has_the_rest_and_its_place_in_thesummary():
    null = [_terms(1.0) for _ in range(4)]
    before = [_terms(10.0) for _ in range(4)]
    fit = FitResult(("b",), [{}], 1, ho_terms=[_terms(1.0, (3, 5), 2000.0) for _ in range(4)])
    s = score_models([fit], before, null)[0]
    assert s.leftover_ratio > LEFTOVER_REPORT_RATIO
    leftover = {"ratio": s.leftover_ratio, "cells": locate(fit.ho_terms, null)}
    text = summary("explained", s, None, [], [], leftover)
    assert text.startswith("explained by b") and f"what is left is still {s.leftover_ratio:.3g}x" in text
    assert f"{ALL_CHANNELS[5]}, {STAGES[3]}" in text
    small = {**leftover, "ratio": LEFTOVER_REPORT_RATIO / 2}
    assert "what is left" not in summary("explained", s, None, [], [], small)


def test_a_near_total_shrink_beside_a_large_rest_says_how_large_the_gap_was_before():
    """'shrinks by 100 %' beside 'left: 449x' read as a contradiction: a shrink of 99.5 % or more gets a decimal,
    and the rest is put beside what the gap was before, on the same scale (after/G0 · before/after = before/G0)."""
    null = [_terms(1.0) for _ in range(4)]
    before = [_terms(1.0, (3, 5), 2_000_000.0) for _ in range(4)]
    fit = FitResult(("b",), [{}], 1, ho_terms=[_terms(1.0, (3, 5), 5000.0) for _ in range(4)])
    s = score_models([fit], before, null)[0]
    assert 0.995 <= s.shrink < 1.0
    leftover = {"ratio": s.leftover_ratio, "cells": locate(fit.ho_terms, null)}
    text = summary("explained", s, None, [], [], leftover)
    assert f"shrinks by {100 * s.shrink:.1f} %" in text
    was = s.leftover_ratio * s.before / s.after
    assert f"(it was {was:.3g}x before)" in text and was > 100 * s.leftover_ratio


def test_a_single_effect_that_predicts_a_force_before_contact_the_data_lack_is_contradicted():
    from drillgym.eval.diagnosis.channels import GROUP_OF
    from drillgym.eval.diagnosis.pairs import before_contact_cells, single_contradicted

    mask = before_contact_cells("ft_drift")
    approach = STAGES.index("approach")
    force = [c for c, ch in enumerate(ALL_CHANNELS) if GROUP_OF[ch] == "force"]
    assert mask is not None and mask[approach, force].all() and mask.sum() == len(force)
    assert before_contact_cells("density_gradient") is None  # acts only through the cut
    rng = np.random.default_rng(0)
    null = [_terms(1.0) for _ in range(8)]
    before = [_terms(1.0, (4, 0), 50.0 + rng.random()) for _ in range(8)]  # a gap during the cut only

    def drift_fit(extra_before_contact: float) -> FitResult:
        terms = []
        for _ in range(8):
            t = _terms(1.0)
            t.cell_sum[approach, force] += extra_before_contact * (1.0 + 0.1 * rng.random())
            terms.append(t)
        return FitResult(("ft_drift",), [{}], 3, ho_terms=terms)

    wrong = score_models([drift_fit(5.0)], before, null)[0]  # cut gap removed, a force before contact added
    right = score_models([drift_fit(0.0)], before, null)[0]
    assert single_contradicted(wrong, before, null)
    assert not single_contradicted(right, before, null)
