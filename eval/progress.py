"""Progress bars that show on every terminal."""

from __future__ import annotations

import os
import shutil
from typing import IO


def bar_size(stream: IO[str]) -> dict[str, int]:
    """The ``ncols`` and ``nrows`` of a tqdm bar on ``stream``: {} (tqdm sizes it) unless it is a terminal of no size.

    A pseudo-terminal whose size was never set (``docker exec -t``, ``script``, some CI runners) reports 0 × 0;
    tqdm takes one less of each (-1 × -1) and then draws nothing at all (a bar below the last row is hidden).
    There the bar gets ``$COLUMNS`` × ``$LINES`` or 80 × 24.
    """
    try:
        if not stream.isatty():
            return {}
        size = os.get_terminal_size(stream.fileno())
    except (AttributeError, OSError, ValueError):  # no file descriptor, or not a terminal after all
        return {}
    if size.columns > 0 and size.lines > 0:
        return {}
    fallback = shutil.get_terminal_size((80, 24))
    return {"ncols": fallback.columns or 80, "nrows": fallback.lines or 24}
