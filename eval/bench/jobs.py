"""Run a benchmark's episodes and name its controllers: what ``drillgym bench`` and the commands built on it share."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

from tqdm import tqdm

from drillgym.envs.errors import UserError
from drillgym.envs.key_values import split_spec_list
from drillgym.eval.bench.episode import BATCH_MAX, batch_key, close_cached, run_batch
from drillgym.eval.pool import run_unordered


def split_controller_specs(text: str) -> list[str]:
    """``"none,li2023:kp=1,ki=0.5,li2023"`` -> ``["none", "li2023:kp=1,ki=0.5", "li2023"]`` (``--controllers``)."""
    return split_spec_list(text, "--controllers", noun="controller name", example="none,li2023")


def controller_label(spec: str) -> str:
    """A file-name-safe label of a spec: ``"li2023:kp=1.0"`` -> ``"li2023_kp-1.0"``."""
    label = spec.replace(":", "_").replace("=", "-").replace(",", "_")
    return re.sub(r"[^A-Za-z0-9._-]+", "_", label).strip("._") or "controller"


def reference_spec(specs: list[str], name: str | None) -> str:
    """The spec of ``specs`` that ``name`` names, as written or by its :func:`controller_label`; None: the first.

    Raises ``ValueError`` listing the choices when ``name`` names none of them (``--reference``).
    """
    if name is None:
        return specs[0]
    if name in specs:
        return name
    for spec in specs:
        if controller_label(spec) == name:
            return spec
    choices = ", ".join(dict.fromkeys(c for s in specs for c in (s, controller_label(s))))
    raise UserError(f"--reference {name!r} is not one of the --controllers; choose from {choices}")


def batches(jobs: list[Any], workers: int = 1) -> list[list[Any]]:
    """The jobs in batches for :func:`~drillgym.eval.bench.episode.run_batch`, in order.

    Jobs of one :func:`~drillgym.eval.bench.episode.batch_key` go together, at most
    :data:`~drillgym.eval.bench.episode.BATCH_MAX` and at most an even share of all jobs per worker, so that
    ``workers`` processes each get work.
    """
    size = max(1, min(BATCH_MAX, math.ceil(len(jobs) / max(workers, 1))))
    groups: dict[Any, list[Any]] = {}
    for job in jobs:
        groups.setdefault(batch_key(job), []).append(job)
    return [group[k : k + size] for group in groups.values() for k in range(0, len(group), size)]


def run_jobs(
    jobs: list[Any],
    workers: int,
    desc: str = "bench",
    on_row: Callable[[dict[str, Any]], None] | None = None,
) -> list[dict[str, Any]]:
    """Run every job (in-process for ``workers == 1``, else in spawned processes); rows in any order.

    The jobs run in :func:`batches` on the batched engine where their cell allows (the rows are those of the single
    env, bit for bit). ``on_row`` is called with each row as its batch finishes (``drillgym bench`` appends it to
    ``episodes.csv``, so an interrupted or crashed run keeps every finished episode).
    """
    rows = []
    with tqdm(total=len(jobs), desc=desc, unit="ep", disable=None) as bar:  # no bar when not a terminal
        try:
            for _, batch_rows in run_unordered(run_batch, batches(jobs, workers), workers, on_error=_worker_failed):
                bar.update(len(batch_rows))
                for row in batch_rows:
                    rows.append(row)
                    if on_row is not None:
                        on_row(row)
        finally:
            close_cached()  # the envs of an in-process run
    return rows


def _worker_failed(jobs: list[Any], e: Exception) -> list[dict[str, Any]]:
    """A worker that died (not an episode error, which the job runners record) gives error rows for its batch."""
    rows = []
    for job in jobs:
        row = {"suite": job.suite, "scenario": job.scenario, "controller": job.controller, "seed": job.seed}
        rows.append({**row, "error": f"worker failed: {type(e).__name__}: {e}", "log": job.log_name})
    return rows
