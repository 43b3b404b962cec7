"""The withheld-effect benchmark of the diagnosis (``drillgym bench-diagnosis``).

:mod:`~drillgym.eval.diagnosis.bench.cases` lists the cases (an effect the diagnosing simulator is not told
about, its size, the episodes), :mod:`~drillgym.eval.diagnosis.bench.run` writes each case's reality,
diagnoses it blind and scores it, :mod:`~drillgym.eval.diagnosis.bench.on_ray` runs the cases as Ray tasks.
"""
