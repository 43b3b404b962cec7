r"""Where one URScript program ends in the byte stream of a script port (30001, 30002, 30003).

A CB3 compiles what a client sends on its primary, secondary or real-time interface: a ``def NAME():`` or
``sec NAME():`` program up to its closing ``end``, or bare statements, each line on its own (URScript manual,
"Remote control via TCP/IP"; UR's "Client Interface" documentation). ``ur_rtde`` keeps one connection to 30003 open
and sends several programs on it (``sendCustomScript``: the custom function, then its own control program again),
so a chunk may hold more than one program and a program may span chunks.

Rules here:

* line endings: ``\r\n`` is a line end like ``\n`` (the controller reads CRLF programs, e.g. from a Windows
  editor; a lone ``\r`` at the end of a chunk waits for the next chunk);
* a program that starts with ``def`` or ``sec`` (after blank lines) ends at the first unindented ``end`` line --
  nested functions and blocks end on indented ``end`` lines, as PolyScope and ``ur_rtde`` write them;
* anything else is bare statements: the complete lines up to the next ``def`` / ``sec`` line, run as one program;
* leading blank and comment lines belong to no program, nor does the indentation of a program's first line.
"""

from __future__ import annotations

import re

PROGRAM_END_RE = re.compile(rb"\nend[ \t]*\n")
"""An unindented ``end`` line: the end of a top-level ``def`` / ``sec`` program."""
_PROGRAM_START = (b"def ", b"sec ")


def split_programs(inbox: bytearray) -> list[str]:
    r"""Take every complete program off the front of ``inbox`` (in place) and return their texts, in order.

    The texts have ``\n`` line ends and start at their first statement; what remains in ``inbox`` is the start of
    a program still arriving (normalised the same way).
    """
    _normalise(inbox)
    programs: list[str] = []
    while True:
        _drop_leading_blank_and_comment_lines(inbox)
        if not inbox:
            break
        if bytes(inbox[:4]) in _PROGRAM_START:
            m = PROGRAM_END_RE.search(inbox)
            if m is None:
                break
            text = bytes(inbox[: m.end()])
        else:
            text = _bare_statements(inbox)
            if not text:
                break
        del inbox[: len(text)]
        programs.append(text.decode(errors="replace"))
    return programs


def _normalise(inbox: bytearray) -> None:
    if b"\r\n" in inbox:
        inbox[:] = inbox.replace(b"\r\n", b"\n")


def _drop_leading_blank_and_comment_lines(inbox: bytearray) -> None:
    while inbox:
        end = inbox.find(b"\n")
        if end < 0:
            if not inbox.strip():
                inbox.clear()
            return
        line = inbox[:end].strip()
        if line and not line.startswith(b"#"):
            del inbox[: len(inbox[:end]) - len(inbox[:end].lstrip())]  # the statement starts the program
            return
        del inbox[: end + 1]


def _bare_statements(inbox: bytearray) -> bytes:
    """The complete lines before the next ``def`` / ``sec`` line (empty if none is complete yet)."""
    taken = 0
    while True:
        end = inbox.find(b"\n", taken)
        if end < 0:
            return bytes(inbox[:taken])
        if taken and bytes(inbox[taken : taken + 4]) in _PROGRAM_START:
            return bytes(inbox[:taken])
        taken = end + 1
