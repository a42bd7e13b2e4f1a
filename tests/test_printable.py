"""Names and paths are printed with their control characters escaped (runs/printable.py): an
escape sequence in a pattern's name or a path is seen on the terminal, not obeyed."""

from __future__ import annotations

import json
from pathlib import Path

from conftest import assert_clean_error, cli

from actionreasoning.runs.printable import printable

#: Clears the screen, sets the window title, rings the bell.
HOSTILE = "\x1b[2J\x1b]0;owned\x07"


def test_control_characters_are_written_as_escapes() -> None:
    assert printable(f"a{HOSTILE}b") == "a\\x1b[2J\\x1b]0;owned\\x07b"
    assert printable("r\rdel\x7fc1\x85bidi\u202enul\x00") == (
        "r\\x0ddel\\x7fc1\\x85bidi\\u202enul\\x00"
    )
    assert printable("lone \udcff surrogate") == "lone \\udcff surrogate"
    assert printable("a\nnew line") == "a\\x0anew line"  # a one-line message stays one
    assert printable("lines\n\tand tabs, ünïcode °", lines=True) == "lines\n\tand tabs, ünïcode °"
    assert printable("a \x1b[2J table\n", lines=True) == "a \\x1b[2J table\n"


def test_a_pattern_name_with_escape_sequences_is_printed_escaped(tmp_path: Path) -> None:
    brick = {"position": [0.0, 0.0, 0.03]}
    pattern = {"name": f"wall{HOSTILE}", "brick_size": [0.2, 0.095, 0.06], "bricks": [brick]}
    path = tmp_path / "p.json"
    path.write_text(json.dumps(pattern))
    shown = cli("pattern", str(path))
    assert shown.returncode == 0, shown.stderr
    assert "\x1b" not in shown.stdout and "\x07" not in shown.stdout
    assert "wall\\x1b[2J\\x1b]0;owned\\x07" in shown.stdout.replace("\n", "")


def test_a_path_with_escape_sequences_is_named_escaped_in_an_error(tmp_path: Path) -> None:
    missing = tmp_path / f"no{HOSTILE}.json"
    refused = cli("pattern", str(missing))
    assert_clean_error(refused, "no\\x1b[2J\\x1b]0;owned\\x07.json")
    assert "\x1b" not in refused.stderr and "\x07" not in refused.stderr
    refused = cli("tolerances", "--pattern", str(missing))
    assert_clean_error(refused, "no\\x1b[2J")
    assert "\x1b" not in refused.stderr


def test_a_file_name_with_a_newline_is_one_line_and_a_trailing_slash_names_no_file(
    tmp_path: Path,
) -> None:
    written = cli("pattern", "--wall", "0.83", "--out", "a\nb.json", cwd=tmp_path)
    assert written.returncode == 0, written.stderr
    assert written.stdout.splitlines()[-1] == "wrote a\\x0ab.json"
    refused = cli("pattern", "--wall", "0.83", "--out", "w.yaml/", cwd=tmp_path)
    assert_clean_error(refused, "--out 'w.yaml/' names no file")
    assert not (tmp_path / "w.yaml").exists()
