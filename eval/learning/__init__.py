"""Learnt policies judged across training seeds.

``drillgym train`` (:mod:`.cli`, one or several seeds) and the across-seed report after Agarwal et al. 2021
(:mod:`.seed_report`).
"""
