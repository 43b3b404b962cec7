"""Reproduction of the papers.

Their published numbers (:mod:`.paper`, the one place they are written), the experiments, the figures, the
report, and ``drillgym reproduce`` (:mod:`.cli`).
"""
