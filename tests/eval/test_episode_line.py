"""``episode_line`` writes an ``episodes.csv`` line as pandas writes a one-row frame, character for character.

``drillgym bench`` appends each finished episode with it, and ``--resume`` reads those lines back to the bit, so the
text must be pandas' own: floats as their shortest exact text (NaN empty, ±inf, −0.0), integers and bools, missing
columns empty, text with commas, quotes or line breaks quoted.
"""

import math

import numpy as np
import pandas as pd
import pytest

from drillgym.eval.bench.episode_line import episode_line
from drillgym.eval.bench.report import EPISODE_COLUMNS, episodes_frame
from drillgym.eval.cli.bench import read_episodes_csv


def _row(rng):
    row = {"suite": "paper", "scenario": "paper", "controller": "li2023:kp=2,y_gain=1.3", "seed": int(rng.integers(99))}
    for c in EPISODE_COLUMNS[4:]:
        row[c] = float(rng.normal() * 10.0 ** rng.integers(-30, 30))
    row["steps"] = int(rng.integers(0, 5000))
    row["failure"] = str(rng.choice(["", "force_limit", "truncated"]))
    row["log"] = ""
    return row


@pytest.mark.parametrize("seed", range(3))
def test_episode_line_is_pandas_one_row_csv_character_for_character(seed):
    rng = np.random.default_rng(seed)
    specials = [0.0, -0.0, math.inf, -math.inf, math.nan, 1e16, 1e-5, 1e-4, 123456789.0, 0.1 + 0.2, np.float64(2.5)]
    texts = ["", "a,b", 'say "no"', "two\nlines", "plain", "ValueError: beta_deg=80 outside [-60, 60]"]
    for k in range(400):
        row = _row(rng)
        row[str(rng.choice(EPISODE_COLUMNS[4:-4]))] = specials[k % len(specials)]
        row["error"] = texts[k % len(texts)]
        if k % 7 == 0:
            del row["wall_time_s"]  # a missing column is empty
        if k % 11 == 0:
            row["hole_offset_mm"] = None
        if k % 13 == 0:
            row["steps"] = pd.NA
        assert episode_line(row) == episodes_frame([row]).to_csv(index=False, header=False), row


def test_lines_read_back_to_the_bit(tmp_path):
    rng = np.random.default_rng(9)
    rows = [_row(rng) for _ in range(50)]
    path = tmp_path / "episodes.csv"
    path.write_text(",".join(EPISODE_COLUMNS) + "\n" + "".join(episode_line(r) for r in rows))
    back = read_episodes_csv(path)
    for r, (_, b) in zip(rows, back.iterrows(), strict=True):
        assert all(float(b[c]) == r[c] for c in EPISODE_COLUMNS[4:] if isinstance(r.get(c), float))
