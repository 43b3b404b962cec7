"""The project's one user-error type: input the caller can fix, as opposed to a bug.

A bad scenario value, an unknown controller, effect or suite name, a malformed spec, plan, table or log, a
contradicting pair of command-line options: each raises :class:`UserError`, with a message that names the input
and what is allowed. The ``drillgym`` command prints a ``UserError`` on one line and exits with status 2; every
other exception (a ``ValueError`` from NumPy, a ``KeyError`` in the project's own code) is a bug and keeps its
traceback (:mod:`drillgym.eval.cli`).

``UserError`` subclasses ``ValueError``, so code that catches ``ValueError`` around the project's calls (and
``pytest.raises(ValueError)``) keeps working.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml


class UserError(ValueError):
    """Bad input that the caller can fix; the message names the input and what is allowed."""


def read_json(path: str | Path) -> Any:
    """The JSON value in the file at ``path``; a file that is not JSON raises :class:`UserError` naming it.

    A missing or unreadable file raises ``OSError`` as usual (the command prints that on one line too).
    """
    text = Path(path).read_text()
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(f"{path}: not valid JSON ({e})") from e


def read_yaml(path: str | Path) -> Any:
    """The YAML value in the file at ``path`` (None for an empty file); a file that is not YAML raises :class:`UserError`.

    A missing or unreadable file raises ``OSError`` as usual.
    """
    text = Path(path).read_text()
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise UserError(f"{path}: not valid YAML ({' '.join(str(e).split())})") from e
