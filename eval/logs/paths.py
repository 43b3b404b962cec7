"""Where an episode log lives: ``<name>.parquet`` when complete, ``<name>/`` while written (or crashed)."""

from __future__ import annotations

from pathlib import Path

from drillgym.envs.errors import UserError

SUFFIX = ".parquet"
HEADER_FILE = "header.json"
PART_GLOB = "part-*.parquet"


def log_paths(path: str | Path) -> tuple[Path, Path]:
    """``(directory, compacted file)`` of the log named by ``path`` (either form, suffix optional)."""
    p = Path(path)
    stem = p.name[: -len(SUFFIX)] if p.name.endswith(SUFFIX) else p.name
    if not stem:
        raise UserError(f"{path!s} does not name an episode log")
    return p.with_name(stem), p.with_name(stem + SUFFIX)


def part_name(index: int) -> str:
    """File name of part ``index`` (0-based): ``part-00000.parquet``."""
    return f"part-{index:05d}{SUFFIX}"
