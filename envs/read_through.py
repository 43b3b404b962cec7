"""Fields read from an episode's named state on demand, while the compiled step runs the episode.

The single env keeps its episode in Python objects (the env, its path, the cell, the cell's tip balance) that
the Python step, the unmodelled effects and the rest of the project read. When the compiled step
(:mod:`drillgym.envs.compiled_step`) runs the episode, the truth is the episode's state record instead, and
copying it into the objects after every step would cost more than the step. So each object's mutable fields
leave it: the first read of one of them after a step asks the state for all of that object's fields
(:class:`ReadThrough`), which stay until the next step (:func:`forget`). A step that nobody reads after copies
nothing. :func:`detach` puts the fields back for good (at the next ``reset``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

Reader = Callable[[], dict[str, Any]]
"""Returns an object's fields, by name, from the state as it is now."""


class ReadThrough:
    """Mixin of the objects whose fields the compiled step keeps in the state (:func:`attach`)."""

    def __getattr__(self, name: str) -> Any:
        """A field held by the state: every field of this object is read from it (called only for a missing attribute)."""
        d = self.__dict__
        reader = d.get("_state_reader")
        if reader is None or name.startswith("__"):
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        d["_state_read"] = _fill(d, reader)
        if name not in d:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        return d[name]

    def __getstate__(self) -> dict[str, Any]:
        """A snapshot for pickle and ``copy``: every field as the state holds it now, and no reader.

        Without it a deep copy would keep reading the original episode's state, and pickle would meet a closure.
        """
        d = dict(self.__dict__)
        reader = d.pop("_state_reader", None)
        d.pop("_state_read", None)
        if reader is not None:
            _fill(d, reader)
        return d


def attach(obj: ReadThrough, reader: Reader) -> None:
    """From now on ``obj``'s fields (those ``reader`` returns) are read from the state."""
    d = obj.__dict__
    d["_state_reader"] = reader
    d["_state_read"] = tuple(reader())
    forget(obj)


def forget(obj: ReadThrough) -> None:
    """Drop the fields read since the last step (the state moved on); a no-op when none were read."""
    d = obj.__dict__
    names = d.pop("_state_read", None)
    if names:
        for name in names:
            d.pop(name, None)


def detach(obj: ReadThrough) -> None:
    """Put every field back into ``obj``, read from the state now, and stop reading through."""
    d = obj.__dict__
    reader = d.pop("_state_reader", None)
    d.pop("_state_read", None)
    if reader is not None:
        _fill(d, reader)


def _fill(d: dict[str, Any], reader: Reader) -> tuple[str, ...]:
    """The fields ``reader`` returns into the instance dict ``d``, but those written since the step; their names."""
    values = reader()
    for key, value in values.items():
        d.setdefault(key, value)
    return tuple(values)
