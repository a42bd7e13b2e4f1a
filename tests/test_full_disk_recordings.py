"""A recording that cannot be finished on a full disk (here a real file size limit, which
fails the writes the way a full disk does) is never left under its final name: the run
ends non-zero with one line naming the file, its finished trials kept, and `report`
copies no video that is not whole."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03]}],
}
#: Larger than results.jsonl and run.json, smaller than a trial's video or recording.
FILE_LIMIT = 30_000


def limited() -> None:
    """Writes past the limit fail with EFBIG (SIGXFSZ ignored), in the run, its film
    process and the encoder alike, as on a disk that is full."""
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (FILE_LIMIT, FILE_LIMIT))


def eval_full(
    tmp_path: Path, out: Path, *options: str, full: bool = True
) -> subprocess.CompletedProcess[str]:
    """Two classical trials of one brick into ``out``, on a full disk unless not ``full``."""
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    args = ["eval", "--method", "classical", "--pattern", str(pattern), "--physics", "precise",
            "--trials", "2", "--out", str(out), *options]  # fmt: skip
    return subprocess.run(
        [sys.executable, "-m", "actionreasoning", *args],
        capture_output=True,
        text=True,
        preexec_fn=limited if full else None,
        timeout=600,
    )


@pytest.mark.slow  # a whole trial each
@pytest.mark.parametrize(
    ("options", "final"),
    [(["--video"], "videos/trial_000_ok.mp4"), (["--rerun"], "rerun/trial_000.rrd")],
)
def test_a_recording_that_does_not_fit_ends_the_run_and_leaves_no_file(
    tmp_path: Path, options: list[str], final: str
) -> None:
    out = tmp_path / "run"
    run = eval_full(tmp_path, out, *options)
    # Before, the video was cut short by the encoder without a word and the run ended 0;
    # the recording was cut short by the write and stayed under its final name.
    assert run.returncode == 2, run.stderr
    assert run.stderr.count("\n") == 1, run.stderr
    assert run.stderr.startswith(f"error: cannot write {out / final}: "), run.stderr
    assert "1 finished trial kept in results.jsonl" in run.stderr
    assert len((out / "results.jsonl").read_text().splitlines()) == 1
    folder = (out / final).parent
    assert not folder.exists() or list(folder.iterdir()) == []  # neither final nor partial


@pytest.mark.slow  # three whole trials
def test_the_same_command_again_says_which_video_is_missing_and_how_to_make_it(
    tmp_path: Path,
) -> None:
    """Before, the command the error asks for ran the trial left and said nothing of the
    video the resume does not make."""
    out = tmp_path / "run"
    eval_full(tmp_path, out, "--video")  # its trial 0 is in results.jsonl, its video not
    again = eval_full(tmp_path, out, "--video", full=False)
    assert again.returncode == 0, again.stderr
    notes = [line for line in again.stdout.splitlines() if line.startswith("missing from")]
    assert notes == [
        f"missing from {out}: video of trial 0, not written when those trials ran; a resume "
        "runs no finished trial again: to make them, run the same command with a new --out"
    ]
    assert [path.name for path in (out / "videos").iterdir()] == ["trial_001_ok.mp4"]


@pytest.mark.slow  # a whole trial
def test_report_copies_no_video_that_is_not_whole(tmp_path: Path) -> None:
    out = tmp_path / "run"
    eval_full(tmp_path, out, "--video")  # its trial 0 is in results.jsonl, its video not
    videos = out / "videos"
    videos.mkdir(exist_ok=True)
    cut = b"\0\0\0\x20ftypisom\0\0\2\0isomiso2avc1mp41" + b"\0\0\x10\0moov" + b"\0" * 100
    (videos / "trial_000_ok.mp4").write_bytes(cut)  # left by an earlier version
    (videos / "trial_000_ok.mp4.partial").write_bytes(cut)
    command = ["report", str(out), "--out", str(tmp_path / "report")]
    report = subprocess.run(
        [sys.executable, "-m", "actionreasoning", *command],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert report.returncode == 0, report.stderr
    assert not (tmp_path / "report" / "videos").exists()
    assert "<video" not in (tmp_path / "report" / "report.html").read_text()


def test_a_run_json_that_does_not_fit_names_it_and_leaves_nothing(tmp_path: Path) -> None:
    """Room for the lock's line, not for run.json: before, the error named the folder and a
    half-written run.tmp was left beside an empty run.lock."""
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    out = tmp_path / "run"

    def tiny() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))

    run = subprocess.run(
        [sys.executable, "-m", "actionreasoning", "eval", "--method", "classical",
         "--pattern", str(pattern), "--trials", "1", "--out", str(out)],
        capture_output=True, text=True, preexec_fn=tiny, timeout=600,
    )  # fmt: skip
    assert run.returncode == 2 and run.stderr.count("\n") == 1, run.stderr
    assert f"cannot write {out / 'run.json'}: File too large" in run.stderr
    assert "no trial has run yet" in run.stderr
    assert not out.exists()
