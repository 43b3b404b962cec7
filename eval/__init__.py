"""The jobs behind the ``drillgym`` command (:mod:`.cli`), one subpackage per kind of job.

``bench`` (controllers on scenario suites, ``tune-entry``), ``perf`` (``bench-speed``, ``bench-rtde``),
``reproduce`` (the papers' numbers and their reproduction), ``calibration``, ``learning`` (``train`` and the
across-seed report), ``real`` (``run``, ``ft-check``), ``diagnosis`` (sim-to-real gap), ``explain``
(``explain-paper``), ``logs`` (episode logs) and ``scale`` (Ray).
"""

from drillgym import training as training  # registers the ``residual:PATH`` controllers for every job below
