"""Progress bars show on a terminal that reports no size."""

import os
import sys

import pytest
from tqdm import tqdm

from drillgym.eval.progress import bar_size

pty = pytest.importorskip("pty")


def _read_all(fd: int) -> bytes:
    import select

    out = b""
    while select.select([fd], [], [], 0.5)[0]:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            break
        if not chunk:
            break
        out += chunk
    return out


@pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals")
def test_a_bar_on_a_terminal_of_no_size_is_drawn(monkeypatch):
    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.delenv("LINES", raising=False)
    master, slave = pty.openpty()  # never sized: 0 x 0, as docker exec -t or script leave it
    with os.fdopen(slave, "w") as stream:
        monkeypatch.setattr(sys, "stderr", stream)  # tqdm sizes a bar from the terminal only on stderr or stdout
        size = bar_size(sys.stderr)
        assert size["ncols"] > 0 and size["nrows"] > 0
        bar = tqdm(total=3, desc="diagnose", file=sys.stderr, disable=None, **size)
        bar.update(3)
        bar.close()
        stream.flush()
        text = _read_all(master).decode(errors="replace")
    os.close(master)
    assert "diagnose" in text and "3/3" in text


@pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals")
def test_a_sized_terminal_and_a_file_leave_the_bar_to_tqdm(tmp_path):
    import fcntl
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    with os.fdopen(slave, "w") as stream:
        assert bar_size(stream) == {}
    os.close(master)
    with open(tmp_path / "log.txt", "w") as f:
        assert bar_size(f) == {}
