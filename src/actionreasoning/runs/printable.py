"""Text from outside (pattern names, paths, messages that quote them) made safe to print.

A name or a path can hold terminal control sequences: ``ESC [ 2 J`` clears the screen,
``ESC ] 0 ; ... BEL`` sets the window title, U+202E turns the text after it around, and a
newline in a file name splits a one-line message in two. Printed raw, they act on the
user's terminal instead of being read. :func:`printable` writes each such character as its
Python escape (``\\x1b``, ``\\u202e``, ``\\x0a``), so it is seen, not obeyed.
"""

from __future__ import annotations

import re

#: DEL and the C1 controls, the bidirectional marks, overrides and isolates, and lone
#: surrogates (bytes a file name could not decode), which no terminal encoding can write;
#: with the C0 controls, all of them (one line), or all but the newline and the tab (lines).
_NOT_C0 = "\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069\ud800-\udfff"
_ONE_LINE = re.compile(f"[\x00-\x1f{_NOT_C0}]")
_LINES = re.compile(f"[\x00-\x08\x0b-\x1f{_NOT_C0}]")


def printable(text: str, *, lines: bool = False) -> str:
    """``text`` with every control character written as its escape; with ``lines`` (text
    of many lines: a prompt, a table), newlines and tabs are kept."""
    return (_LINES if lines else _ONE_LINE).sub(_escaped, text)


def _escaped(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"
