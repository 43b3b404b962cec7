"""Speed and timing benchmarks.

The simulated cell's step (``drillgym bench-speed``, :mod:`.speed`) and the 125 Hz servo stream through
``ur_rtde`` (``drillgym bench-rtde``, :mod:`.rtde`).
"""
