"""Streaming benchmark outputs: each finished episode lands on disk as soon as the driver receives it.

``episodes.csv`` gets one appended row per episode in completion order (``drillgym bench`` rewrites it
sorted at the end, identical to a local run), the episode's log is written under ``logs/``, and
``summary.csv`` is refreshed every ``refresh_s`` seconds. A driver that dies keeps every row and log it
had received.
"""

from __future__ import annotations

import os
import shutil
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from drillgym.envs.metrics import METRIC_NAMES
from drillgym.eval.bench.report import episodes_frame
from drillgym.eval.bench.summary import summarize


class StreamingSink:
    """Writes rows, logs and a running summary into a benchmark's output folder."""

    def __init__(self, out: Path, groups: Sequence[tuple[str, str, str]], refresh_s: float = 10.0) -> None:
        """Start ``out/episodes.csv`` afresh.

        Args:
            out: the output folder (created if needed).
            groups: ``(suite, scenario, controller)`` groups of ``summary.csv``, in order.
            refresh_s: least time between two rewrites of ``summary.csv`` (s).
        """
        self.out = Path(out)
        self.out.mkdir(parents=True, exist_ok=True)
        self.groups = list(groups)
        self.refresh_s = refresh_s
        self.rows: list[dict[str, Any]] = []
        self._csv = self.out / "episodes.csv"
        self._csv.unlink(missing_ok=True)
        self._last_refresh = time.monotonic()

    def add(self, row: dict[str, Any], files: Mapping[str, bytes] | None = None) -> None:
        """Record one finished episode: its log files (paths relative to ``out``), then its row."""
        self.extend([(row, files or {})])

    def extend(self, episodes: Sequence[tuple[dict[str, Any], Mapping[str, bytes]]]) -> None:
        """Record finished episodes (one ``episodes.csv`` append for all of them)."""
        if not episodes:
            return
        for row, files in episodes:
            if files:
                self._replace_log(str(row.get("log") or ""))
                for rel, data in files.items():
                    _write_atomic(self.out / rel, data)
        rows = [row for row, _ in episodes]
        episodes_frame(rows).to_csv(self._csv, mode="a", header=not self.rows, index=False)
        self.rows.extend(rows)
        if time.monotonic() - self._last_refresh >= self.refresh_s:
            self.write_summary()

    def write_summary(self) -> None:
        """Rewrite ``summary.csv`` from the episodes received so far (errors left out)."""
        ok = [r for r in self.rows if not r.get("error")]
        if ok:
            frame = summarize(episodes_frame(ok), METRIC_NAMES, self.groups)
            tmp = self.out / "summary.csv.tmp"
            frame.to_csv(tmp, index=False)
            os.replace(tmp, self.out / "summary.csv")
        self._last_refresh = time.monotonic()

    def _replace_log(self, log_name: str) -> None:
        """Remove an older log of that name (a finished file or a crashed run's directory)."""
        if not log_name:
            return
        path = self.out / log_name
        stem = path.with_suffix("") if path.suffix == ".parquet" else path
        if stem.is_dir():
            shutil.rmtree(stem)
        path.unlink(missing_ok=True)


def _write_atomic(path: Path, data: bytes) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)
