"""One ``episodes.csv`` line of a finished episode, written as pandas writes it, without building a frame.

``drillgym bench`` appends each finished episode to ``episodes.csv`` at once (``EpisodeAppender``), so that a crash
keeps every finished episode. A one-row :class:`pandas.DataFrame` and its ``to_csv`` cost ≈ 1.4 ms a line, a quarter
of a 3,200-episode benchmark's time; :func:`episode_line` writes the same text with the :mod:`csv` module (≈ 30 µs):
the columns of :data:`~drillgym.eval.bench.report.EPISODE_COLUMNS` in order, a missing or NaN value empty, a float as
``repr`` gives it (the shortest text that reads back to the same bits, as pandas writes a float), an integer and a bool
as ``str``, text quoted where it holds a comma, a quote or a line break (``tests/eval/test_episode_line.py`` compares
it with pandas).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from typing import Any

import numpy as np
import pandas as pd

from drillgym.eval.bench.report import EPISODE_COLUMNS


def _cell(value: Any) -> str:
    """One value as ``DataFrame.to_csv`` writes it in a one-row frame (``na_rep=""``)."""
    if value is None or value is pd.NA or (isinstance(value, float | np.floating) and math.isnan(value)):
        return ""
    if isinstance(value, bool | np.bool_):
        return str(bool(value))
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return repr(float(value))
    return str(value)


def episode_line(row: Mapping[str, Any]) -> str:
    """``episodes_frame([row]).to_csv(index=False, header=False)``: one line, with its line break."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([_cell(row.get(c)) for c in EPISODE_COLUMNS])
    return buf.getvalue()
