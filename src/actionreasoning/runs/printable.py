"""Text from outside (pattern names, paths, messages that quote them) made safe to print.

A name or a path can hold terminal control sequences: ``ESC [ 2 J`` clears the screen,
``ESC ] 0 ; ... BEL`` sets the window title, U+202E turns the text after it around. Printed
raw, they act on the user's terminal instead of being read. :func:`printable` writes each
such character as its Python escape (``\\x1b``, ``\\u202e``), so it is seen, not obeyed.
"""

from __future__ import annotations

import re

#: C0 controls but the newline and the tab, DEL and the C1 controls, the bidirectional
#: overrides and isolates, and lone surrogates (bytes a file name could not decode), which
#: no terminal encoding can write.
_UNPRINTABLE = re.compile(
    "[\x00-\x08\x0b-\x1f\x7f-\x9f\u200e\u200f\u202a-\u202e\u2066-\u2069\ud800-\udfff]"
)


def printable(text: str) -> str:
    """``text`` with every control character written as its escape; newlines and tabs kept."""
    return _UNPRINTABLE.sub(_escaped, text)


def _escaped(match: re.Match[str]) -> str:
    code = ord(match.group())
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"
