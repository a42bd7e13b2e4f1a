"""A run of a billion trials starts at once in bounded memory, serial or with workers, and
resumes like any other: trials are made as the engine takes them, not listed up front."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03]}],
}
#: Address space each process of the run may take: a list of a billion jobs does not fit.
MEMORY_LIMIT = 1 << 30
#: How long the first trial may take to appear, however loaded the machine (not a timing test).
PATIENCE_S = 300.0


def limited() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def trials_in(results: Path) -> list[int]:
    if not results.exists():
        return []
    text = results.read_text()
    return [json.loads(line)["trial"] for line in text[: text.rfind("\n") + 1].splitlines()]


def run_until(args: list[str], results: Path, lines: int) -> subprocess.CompletedProcess[str]:
    """Start the run, stop it with Ctrl-C once ``results`` holds ``lines`` trials."""
    process = subprocess.Popen(
        [sys.executable, "-m", "actionreasoning", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=limited,
    )
    deadline = time.monotonic() + PATIENCE_S
    while len(trials_in(results)) < lines:
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            stdout, stderr = process.communicate()
            pytest.fail(f"no trial {lines - 1} (rc {process.returncode}): {stderr[-2000:]}")
        time.sleep(0.1)
    process.send_signal(signal.SIGINT)
    stdout, stderr = process.communicate(timeout=120)
    return subprocess.CompletedProcess(process.args, process.returncode, stdout, stderr)


@pytest.mark.slow
def test_a_billion_trials_start_at_once_and_resume_with_workers(tmp_path: Path) -> None:
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    out = tmp_path / "run"
    args = ["eval", "--method", "classical", "--pattern", str(pattern), "--physics", "precise",
            "--trials", "1000000000", "--out", str(out)]  # fmt: skip
    first = run_until(args, out / "results.jsonl", 1)
    # Before, the job list was built first: MemoryError, and no trial ran.
    assert first.returncode == 130, first.stderr
    # The line is written before its progress line is printed: Ctrl-C may fall in between.
    rows = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert rows[0]["trial"] == 0 and rows[0]["success"] is True
    done = len(trials_in(out / "results.jsonl"))
    second = run_until([*args, "--workers", "2"], out / "results.jsonl", done + 2)
    assert second.returncode == 130, second.stderr
    assert f"resuming: {done} of 1000000000 trials already in results.jsonl" in second.stdout
    trials = trials_in(out / "results.jsonl")
    assert len(set(trials)) == len(trials) and set(range(done)) <= set(trials)
