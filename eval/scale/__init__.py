"""Scale-out on Ray: benchmark grids as Ray tasks, residual-training sweeps with Ray Tune.

Nothing here is imported by the env, the controllers, the local benchmark or a single training run:
Ray is an optional dependency (``pip install drillgym[ray]``), loaded only by ``--ray`` / ``--sweep``.
See ``docs/scale-out.md``.
"""
