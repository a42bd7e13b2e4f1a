"""`report` and a resume read results.jsonl line by line in bounded memory: a tail far
larger than the memory a process may take is refused with its line, never read whole."""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03]}],
}
#: Address space each process may take.
MEMORY_LIMIT = 512 << 20
#: The tail: one and a half times that, written sparse (NUL bytes, no disk taken).
TAIL = MEMORY_LIMIT * 3 // 2


def limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))


def cli(*args: str | Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "actionreasoning", *map(str, args)],
        capture_output=True,
        text=True,
        preexec_fn=limited,
        timeout=600,
    )


@pytest.mark.slow
def test_a_tail_larger_than_memory_is_refused_by_report_and_resume(tmp_path: Path) -> None:
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    out = tmp_path / "run"
    args = ["eval", "--method", "classical", "--pattern", pattern, "--physics", "precise",
            "--out", out]  # fmt: skip
    first = cli(*args, "--trials", "1")
    assert first.returncode == 0, first.stderr
    results = out / "results.jsonl"
    line = results.read_bytes()
    with results.open("ab") as handle:  # a stray write far past the end: one huge line
        handle.truncate(len(line) + TAIL)
    for run in (cli("report", out, "--out", tmp_path / "report"), cli(*args, "--trials", "2")):
        # Before, the whole file was read: MemoryError, with a traceback.
        assert run.returncode == 2, run.stderr
        assert run.stderr.count("\n") == 1, run.stderr
        assert "results.jsonl line 2 is longer than 64 MiB: not a trial result" in run.stderr
    assert results.stat().st_size == len(line) + TAIL  # a resume cut nothing
    with results.open("rb") as handle:
        assert handle.read(len(line)) == line
    # A file of NUL bytes alone is no results file (before: "empty", or MemoryError).
    os.truncate(results, 0)
    os.truncate(results, TAIL)
    for run in (cli("report", out, "--out", tmp_path / "report"), cli(*args, "--trials", "2")):
        assert run.returncode == 2, run.stderr
        assert (
            run.stderr == f"error: {results} is not a results file (it holds NUL bytes "
            "where its first line should be)\n"
        )
    assert results.stat().st_size == TAIL
