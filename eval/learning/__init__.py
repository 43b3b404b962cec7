"""Learnt policies judged across training seeds.

``drillgym train`` (:mod:`.cli`, one or several seeds) and the across-seed report after Agarwal et al. 2021:
its statistics (:mod:`.seed_stats`), its acceptance rules (:mod:`.seed_checks`) and the report (:mod:`.seed_report`).
"""
