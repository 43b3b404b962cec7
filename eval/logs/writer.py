"""Crash-safe Parquet writer of one episode log.

A Parquet file is unreadable without its footer, so a log is written as a directory ``<name>/``:
``header.json`` first, then numbered parts ``part-00000.arrow``, ... each a complete small Arrow IPC
file (written to a temporary name and renamed, so a part is either whole or absent). ``close()``
compacts the parts into ``<name>.parquet`` with the header in its schema metadata and removes the
directory; a crash leaves the directory, readable up to the last flush (:mod:`drillgym.eval.logs.reader`).
"""

from __future__ import annotations

import itertools
import os
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from drillgym.envs.errors import UserError
from drillgym.eval.logs.header import dumps
from drillgym.eval.logs.paths import HEADER_FILE, log_paths, part_name
from drillgym.eval.logs.schema import ARROW_SCHEMA, HEADER_METADATA_KEY, SIM_COLUMNS

FLUSH_ROWS = 100
"""Rows per part: 1 s of F/T samples at 100 Hz."""


def schema_for(source: str) -> pa.Schema:
    """Arrow schema of a log from ``source``: a real-cell log has no ``sim_`` columns."""
    if source == "sim":
        return ARROW_SCHEMA
    return pa.schema([f for f in ARROW_SCHEMA if f.name not in SIM_COLUMNS])


class EpisodeLogWriter:
    """Append rows of one episode; parts on disk every ``flush_rows`` rows; compact on ``close()``."""

    def __init__(
        self, path: str | Path, header: dict[str, Any], flush_rows: int = FLUSH_ROWS, overwrite: bool = False
    ) -> None:
        """Create ``<name>/`` and write ``header.json``.

        Args:
            path: the log, ``<name>.parquet`` (or ``<name>``).
            header: JSON-ready header (:func:`drillgym.eval.logs.build_header`); its ``source`` picks the columns.
            flush_rows: rows buffered before a part is written.
            overwrite: replace an existing log of that name instead of raising ``FileExistsError``.
        """
        if flush_rows < 1:
            raise UserError(f"flush_rows={flush_rows} must be >= 1")
        self.dir, self.path = log_paths(path)
        for existing in (self.dir, self.path):
            if existing.exists():
                if not overwrite:
                    raise FileExistsError(f"{existing} exists; pass overwrite=True to replace it")
                if existing.is_dir():
                    shutil.rmtree(existing)
                else:
                    existing.unlink()
        self.header_json = dumps(header)
        self.schema = schema_for(str(header.get("source", "sim")))
        self.flush_rows = flush_rows
        self.rows_written = 0
        self.closed = False
        self.compacted = False
        self._parts: list[pa.Table] = []
        self._chunks: list[Mapping[str, Sequence[Any] | Any]] = []
        self._buffered = 0
        self.dir.mkdir(parents=True)
        _atomic_write_bytes(self.dir / HEADER_FILE, self.header_json.encode())

    def append(self, columns: Mapping[str, Sequence[Any] | Any]) -> None:
        """Append rows given column-wise (every schema column, equal lengths: lists or NumPy arrays).

        The columns are kept as given until their part is written: the caller must not change them afterwards.
        """
        if self.closed:
            raise RuntimeError(f"{self.path}: log already closed")
        missing = [n for n in self.schema.names if n not in columns]
        if missing:
            raise KeyError(f"episode log rows lack column(s) {missing}")
        lengths = {len(columns[n]) for n in self.schema.names}
        if len(lengths) != 1:
            raise ValueError(f"episode log columns have different lengths {sorted(lengths)}")
        self._chunks.append(columns)
        self._buffered += lengths.pop()
        if self._buffered >= self.flush_rows:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows as the next part (nothing if the buffer is empty).

        A part is a temporary file (compaction rewrites its rows), so it is an Arrow IPC file, the rows as they
        are in memory: 0.18 ms for 100 rows, against 1.25 ms for a Parquet file written plain.
        """
        if not self._buffered:
            return
        table = pa.Table.from_pydict(
            {n: _joined([c[n] for c in self._chunks]) for n in self.schema.names}, schema=self.schema
        )
        target = self.dir / part_name(len(self._parts))
        tmp = target.with_name(target.name + ".tmp")
        with pa.OSFile(str(tmp), "wb") as sink, pa.ipc.new_file(sink, self.schema) as out:
            out.write_table(table)
        os.replace(tmp, target)
        self._parts.append(table)
        self.rows_written += table.num_rows
        self._chunks = []
        self._buffered = 0

    def close(self) -> Path:
        """Flush, compact the parts into ``<name>.parquet`` (header in its metadata), remove ``<name>/``.

        The parts written are also kept in memory, so compaction does not read them back.
        """
        if self.closed:
            return self.path
        self.flush()
        table = pa.concat_tables(self._parts) if self._parts else self.schema.empty_table()
        table = table.replace_schema_metadata({HEADER_METADATA_KEY: self.header_json.encode()})
        tmp = self.path.with_name(self.path.name + ".tmp")
        # Without dictionary pages: a log's float columns rarely repeat, and the file is written in half the time
        # and comes out a few per cent smaller (2,040 rows: 1.2 against 2.3 ms, 204 against 217 kB).
        pq.write_table(table, tmp, use_dictionary=False)
        os.replace(tmp, self.path)
        shutil.rmtree(self.dir)
        self.closed = self.compacted = True
        return self.path

    def abandon(self) -> Path:
        """Flush and stop, leaving the directory as a crash would (the episode did not finish)."""
        if self.compacted:
            return self.path
        if not self.closed:
            self.flush()
            self.closed = True
        return self.dir


def _joined(chunks: list[Any]) -> Any:
    """One column of several appends: the lone chunk, the lists chained, or the arrays concatenated."""
    if len(chunks) == 1:
        return chunks[0]
    if all(isinstance(c, list) for c in chunks):
        return list(itertools.chain.from_iterable(chunks))
    return np.concatenate([np.asarray(c) for c in chunks])


def _atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_bytes(data)
    os.replace(tmp, path)
