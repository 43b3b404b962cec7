"""``drillgym bench-diagnosis --ray``: the benchmark's cases as Ray tasks, one CPU each.

A case (generate a reality, diagnose it with every candidate, score it) takes minutes, so Ray's
overhead is negligible and the benchmark scales with the cluster's CPUs up to its number of cases. A
case's row carries its ``diagnosis.json``, which the driver writes: no shared file system is needed. A
case whose worker process dies is run again (``max_retries``); past that it is an error row.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import ray

from drillgym.eval.diagnosis.bench.run import CaseJob, error_row, run_case
from drillgym.eval.scale.cluster import ray_session

MAX_RETRIES = 2
"""Times Ray re-runs a case whose worker process died."""


def ray_rows(
    jobs: list[CaseJob], address: str | None = None, num_cpus: int | None = None, max_retries: int = MAX_RETRIES
) -> Iterator[dict[str, Any]]:
    """Run every case as a Ray task; yield the rows as the cases finish.

    Args:
        jobs: the cases.
        address: Ray address (see :func:`drillgym.eval.scale.cluster.ray_session`); None starts a local instance.
        num_cpus: CPUs of a local instance (default: the machine's).
        max_retries: re-runs of a case whose worker died.
    """
    task = ray.remote(num_cpus=1, max_retries=max_retries, retry_exceptions=False)(run_case)
    with ray_session(address, num_cpus) as session:
        print(session.describe())
        case_of = {task.remote(job): job[0] for job in jobs}
        waiting = list(case_of)
        while waiting:
            done, waiting = ray.wait(waiting, num_returns=1)
            ref = done[0]
            try:
                yield ray.get(ref)
            except (ray.exceptions.RayError, OSError) as e:
                yield error_row(case_of[ref], f"worker failed: {type(e).__name__}: {e}")
