"""Model scores built by hand, for the diagnosis's naming rules (no simulator)."""

from __future__ import annotations

import numpy as np

from drillgym.eval.diagnosis.fit import FitResult
from drillgym.eval.diagnosis.gap import Terms
from drillgym.eval.diagnosis.rank import ModelScore


def stub_score(
    names: tuple[str, ...],
    before: float,
    after: float,
    null_gap: float,
    score_draws: np.ndarray,
    ho_terms: list[Terms] | None = None,
) -> ModelScore:
    """A fitted model with the given held-out gaps and bootstrap score draws (score: their mean)."""
    fit = FitResult(names=names, params=[{} for _ in names], n_params=len(names), ho_terms=ho_terms or [])
    return ModelScore(
        fit=fit,
        before=before,
        after=after,
        shrink=(before - after) / (before - null_gap),
        ci_low=0.0,
        ci_high=1.0,
        score=float(np.mean(score_draws)),
        score_draws=score_draws,
    )
