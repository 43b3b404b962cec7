"""Benchmarks of controllers on scenario suites: the suites, one episode, the run, its summary, report and plots.

``drillgym bench`` (:mod:`.cli`) and ``drillgym tune-entry`` (:mod:`.tune_entry`) are its commands.
"""
