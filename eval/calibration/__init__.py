"""Calibration of the entry mechanics on the uncompensated paper run.

The screen (:mod:`.calibrate`), its plot and ``drillgym calibrate`` (:mod:`.cli`).
"""
