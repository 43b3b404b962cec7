"""Diagnosis from published numbers: which unmodelled effect explains Li et al. 2023's compensated runs.

Li's reported results are treated as a real cell's data (:mod:`.observations`); candidate effects and
controller-model errors (:mod:`.candidates`) are fitted on the calibration subset only (the uncompensated
run and the KP 1 run, :mod:`.fit`), ranked with a parameter penalty, and then predict the held-out KP 4
run (:mod:`.run`, ``drillgym explain-paper``). ``docs/explain-paper.md`` describes it and its figures.
"""
