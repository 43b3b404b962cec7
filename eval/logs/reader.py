"""Read an episode log: the compacted ``<name>.parquet`` or the ``<name>/`` directory of a crashed run."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from drillgym.envs.errors import UserError
from drillgym.eval.logs.paths import HEADER_FILE, PART_GLOBS, PART_SUFFIX, log_paths
from drillgym.eval.logs.schema import HEADER_METADATA_KEY
from drillgym.eval.logs.writer import schema_for


class EpisodeLogError(UserError):
    """A log that cannot be read as asked: missing, not a drillgym log, or a corrupt part (named)."""


def read_episode_log(path: str | Path, allow_partial: bool = False) -> tuple[dict[str, Any], pd.DataFrame]:
    """Header and rows of one episode log.

    Args:
        path: ``<name>.parquet`` or ``<name>`` (either names the log); when the compacted file is absent,
            the directory ``<name>/`` left by a run that did not close (crash, kill) is read instead.
        allow_partial: for a directory, skip corrupt or truncated parts (with a warning naming them)
            instead of raising.

    Returns:
        ``(header, table)``: the header dict and one row per F/T sample, in time order.
        ``table.attrs["partial"]`` is True when the rows come from a directory (the run did not close).

    Raises:
        EpisodeLogError: no such log, no header, or a corrupt part (the message names the file).
    """
    p = Path(path)
    directory, compacted = log_paths(p)
    if p.is_file():
        compacted = p
    if compacted.is_file():
        header = _read_compacted(compacted)
        try:
            table = pq.read_table(compacted)
        except (OSError, pa.ArrowException) as e:
            raise EpisodeLogError(f"{compacted}: corrupt or truncated episode log ({e})") from e
        frame = table.replace_schema_metadata(None).to_pandas()
        frame.attrs.update(partial=False, path=str(compacted))
        return header, frame
    if directory.is_dir():
        return _read_directory(directory, allow_partial)
    raise EpisodeLogError(f"no episode log at {p}: neither {compacted} nor {directory}/ exists")


def _read_compacted(path: Path) -> dict[str, Any]:
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowException) as e:
        raise EpisodeLogError(f"{path}: not a readable Parquet file ({e})") from e
    if HEADER_METADATA_KEY not in meta:
        raise EpisodeLogError(f"{path}: no drillgym header in the Parquet metadata; not an episode log")
    try:
        return dict(json.loads(meta[HEADER_METADATA_KEY]))
    except ValueError as e:
        raise EpisodeLogError(f"{path}: unreadable drillgym header in the Parquet metadata ({e})") from e


def _read_directory(directory: Path, allow_partial: bool) -> tuple[dict[str, Any], pd.DataFrame]:
    header_path = directory / HEADER_FILE
    try:
        header = dict(json.loads(header_path.read_text()))
    except (OSError, ValueError) as e:
        raise EpisodeLogError(f"{header_path}: missing or unreadable header ({e})") from e
    schema = schema_for(str(header.get("source", "sim")))
    tables, bad = [], []
    parts = sorted({p for glob in PART_GLOBS for p in directory.glob(glob)}, key=lambda p: p.name)
    for part in parts:
        try:
            tables.append(_read_part(part, schema))
        except (OSError, pa.ArrowException) as e:
            if not allow_partial:
                raise EpisodeLogError(
                    f"{part}: corrupt or truncated log part ({e}); read_episode_log(..., allow_partial=True) "
                    "returns the rows of the readable parts"
                ) from e
            bad.append(part.name)
    if bad:
        warnings.warn(f"{directory}: skipped unreadable part(s) {bad}", RuntimeWarning, stacklevel=3)
    table = pa.concat_tables(tables) if tables else schema.empty_table()
    frame = table.to_pandas()
    frame.attrs.update(partial=True, path=str(directory), skipped_parts=bad)
    return header, frame


def _read_part(part: Path, schema: pa.Schema) -> pa.Table:
    """One part's rows: an Arrow IPC file, or a Parquet file (as earlier versions wrote them)."""
    if part.suffix == PART_SUFFIX:
        with pa.memory_map(str(part)) as source:
            table = pa.ipc.open_file(source).read_all()
        if not table.schema.equals(schema):
            raise pa.ArrowInvalid(f"columns {table.schema.names} are not the log's")
        return table
    return pq.read_table(part, schema=schema)
