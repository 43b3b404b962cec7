"""Where an episode log lives: ``<name>.parquet`` when complete, ``<name>/`` while written (or crashed)."""

from __future__ import annotations

from pathlib import Path

from drillgym.envs.errors import UserError

SUFFIX = ".parquet"
HEADER_FILE = "header.json"
PART_SUFFIX = ".arrow"
"""A part is an Arrow IPC file: written in a sixth of the time of a Parquet file of the same rows."""
PART_GLOBS = ("part-*.arrow", "part-*.parquet")
"""Parts as written now, and as earlier versions wrote them (Parquet files); the reader takes both."""


def log_paths(path: str | Path) -> tuple[Path, Path]:
    """``(directory, compacted file)`` of the log named by ``path`` (either form, suffix optional)."""
    p = Path(path)
    stem = p.name[: -len(SUFFIX)] if p.name.endswith(SUFFIX) else p.name
    if not stem:
        raise UserError(f"{path!s} does not name an episode log")
    return p.with_name(stem), p.with_name(stem + SUFFIX)


def part_name(index: int) -> str:
    """File name of part ``index`` (0-based): ``part-00000.arrow``."""
    return f"part-{index:05d}{PART_SUFFIX}"
