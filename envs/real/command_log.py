"""The log of commands sent to the robot (or, in dry-run, of what would have been sent)."""

from __future__ import annotations

import json
import threading
import time
from collections import deque
from pathlib import Path
from typing import Any, TextIO


class CommandLog:
    """Commands sent (or, in dry-run, that would have been sent): the newest in memory, all in a JSONL file."""

    def __init__(self, path: str | Path | None = None, keep: int = 20000) -> None:
        self.entries: deque[dict[str, Any]] = deque(maxlen=keep)
        self.count = 0
        self._file: TextIO | None = open(path, "w") if path else None
        self._lock = threading.Lock()

    def add(self, name: str, **args: Any) -> None:
        """Record one command (arguments JSON-ready)."""
        entry = {"t": time.monotonic(), "cmd": name, **args}
        with self._lock:
            self.entries.append(entry)
            self.count += 1
            if self._file is not None:
                self._file.write(json.dumps(entry) + "\n")

    def close(self) -> None:
        """Close the file."""
        with self._lock:
            if self._file is not None:
                self._file.close()
                self._file = None
