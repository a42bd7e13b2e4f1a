"""Output directories under abuse, as a user meets it: `demo` into a directory of one's own,
two runs into one directory, a full disk, hand-edited result lines. Real processes, real
files, a real full file system where the machine lets one be mounted."""

from __future__ import annotations

import json
import os
import re
import resource
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import assert_clean_error, cli

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}


@pytest.fixture(scope="module")
def one_brick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("pattern") / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


def eval_args(pattern: Path, out: Path, *extra: str, trials: int = 2) -> list[str]:
    return [
        "eval", "--method", "classical", "--pattern", str(pattern), "--trials", str(trials),
        "--out", str(out), *extra,
    ]  # fmt: skip


@pytest.fixture(scope="module")
def reference(one_brick: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Classical trials of the one-brick pattern, written undisturbed: enough lines to fill
    more than a file size limit a trial can run under."""
    out = tmp_path_factory.mktemp("reference") / "run"
    result = cli(*eval_args(one_brick, out, trials=24))
    assert result.returncode == 0, result.stderr
    return out


def lines_of(out: Path) -> list[bytes]:
    return (out / "results.jsonl").read_bytes().splitlines(keepends=True)


def first_trials_of(reference: Path, out: Path, count: int) -> None:
    """``out`` as the reference run was after its first ``count`` trials."""
    out.mkdir()
    shutil.copy(reference / "run.json", out / "run.json")
    (out / "results.jsonl").write_bytes(b"".join(lines_of(reference)[:count]))


def tree(directory: Path) -> dict[str, bytes]:
    """Every file under ``directory`` with its content."""
    files = (path for path in directory.rglob("*") if path.is_file())
    return {str(path.relative_to(directory)): path.read_bytes() for path in files}


# 1. demo


def test_demo_refuses_a_directory_it_did_not_make(one_brick: Path, tmp_path: Path) -> None:
    mine = tmp_path / "u"
    (mine / "report").mkdir(parents=True)
    (mine / "report.md").write_text("x\n")
    (mine / "report" / "thesis.tex").write_text("precious\n")
    before = tree(mine)
    result = cli("demo", "--pattern", str(one_brick), "--out", str(mine))
    assert_clean_error(result, str(mine), "not empty")
    assert tree(mine) == before
    assert sorted(path.name for path in mine.iterdir()) == ["report", "report.md"]

    a_file = tmp_path / "notes.txt"
    a_file.write_text("keep\n")
    assert_clean_error(cli("demo", "--out", str(a_file)), str(a_file), "not a directory")
    assert a_file.read_text() == "keep\n"


@pytest.mark.slow
def test_demo_writes_a_new_or_empty_directory_and_replaces_its_own(
    one_brick: Path, tmp_path: Path
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    for out in (tmp_path / "new", empty):
        result = cli("demo", "--pattern", str(one_brick), "--out", str(out))
        assert result.returncode == 0, result.stderr
        assert (out / ".actionreasoning-demo").is_file() and (out / "report.md").is_file()
        assert len(list((out / "videos").glob("trial_000_*.mp4"))) == 1  # it films its trial
        (linked,) = re.findall(
            r"\[The video of the build\]\(([^)]+)\)", (out / "report.md").read_text()
        )
        assert (out / linked).read_bytes() == next((out / "videos").iterdir()).read_bytes()
    (empty / "snapshots" / "stale.png").write_bytes(b"old picture")
    (empty / "videos" / "trial_000_stale.mp4").write_bytes(b"old video")
    again = cli("demo", "--pattern", str(one_brick), "--seed", "1", "--out", str(empty))
    assert again.returncode == 0, again.stderr
    assert not (empty / "snapshots" / "stale.png").exists()
    assert not (empty / "videos" / "trial_000_stale.mp4").exists()
    assert json.loads(lines_of(empty)[0])["seed"] == 1 and len(lines_of(empty)) == 1


# 2. two runs into one directory


@pytest.mark.slow
def test_a_second_run_into_a_directory_in_use_is_refused_naming_the_holder(
    one_brick: Path, tmp_path: Path
) -> None:
    out = tmp_path / "r"
    with socket.socket() as silent:  # a model server that accepts and never answers
        silent.bind(("127.0.0.1", 0))
        silent.listen(8)
        url = f"http://127.0.0.1:{silent.getsockname()[1]}/v1"
        first = subprocess.Popen(
            [sys.executable, "-m", "actionreasoning", "eval", "--llm", "openai:m", "--base-url",
             url, "--llm-timeout", "600", "--trials", "2", "--out", str(out)],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        try:
            lock = out / "run.lock"
            deadline = time.monotonic() + 120
            while not (lock.is_file() and f"pid {first.pid} " in lock.read_text()):
                assert first.poll() is None, "the first run ended"
                assert time.monotonic() < deadline, "the first run never locked its directory"
                time.sleep(0.05)
            stored = out / "run.json"  # not yet written: the first still asks its server
            assert not stored.exists()
            second = cli(*eval_args(one_brick, out, "--seed", "7"))
            assert_clean_error(second, str(out), f"pid {first.pid} on {socket.gethostname()}")
            assert not stored.exists()  # the refused run wrote nothing
            results = out / "results.jsonl"
            assert not results.exists() or results.stat().st_size == 0
        finally:
            first.send_signal(signal.SIGKILL)
            first.wait()
    # The OS dropped the lock with its holder: the directory (no trial in it) is free again.
    third = cli(*eval_args(one_brick, out, "--seed", "7"))
    assert third.returncode == 0, third.stderr
    assert json.loads((out / "run.json").read_text())["seed"] == 7
    assert [json.loads(line)["trial"] for line in lines_of(out)] == [0, 1]


# 4. a full disk


def run_limited(args: list[str], max_file_bytes: int) -> subprocess.CompletedProcess[str]:
    """The command with no file it writes allowed past ``max_file_bytes`` (RLIMIT_FSIZE: a
    write beyond is cut short, the next one fails with EFBIG), as on a nearly full disk."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (max_file_bytes, max_file_bytes))

    return subprocess.run(
        [sys.executable, "-m", "actionreasoning", *args],
        capture_output=True, text=True, timeout=600, preexec_fn=limit,
    )  # fmt: skip


#: Over the largest file a trial writes outside --out (the arm's URDF, in a temporary
#: directory), under the sheet of stage pictures of a trial.
OTHER_FILES_BYTES = 20 * 1024


@pytest.mark.slow
def test_a_short_write_of_a_result_ends_the_run_keeping_whole_lines(
    one_brick: Path, reference: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    lines = lines_of(reference)
    kept = next(k for k in range(len(lines)) if len(b"".join(lines[:k])) > OTHER_FILES_BYTES)
    first_trials_of(reference, out, kept)
    limit = len(b"".join(lines[:kept])) + len(lines[kept]) // 2  # the next line half fits
    result = run_limited(eval_args(one_brick, out, trials=kept + 1), limit)
    where = str(out / "results.jsonl")
    assert_clean_error(result, where, "File too large", f"{kept} finished trials kept")
    assert lines_of(out) == lines[:kept]
    resumed = cli(*eval_args(one_brick, out, trials=kept + 1))
    assert resumed.returncode == 0, resumed.stderr
    assert lines_of(out) == lines[: kept + 1]


@pytest.mark.slow
def test_a_trial_whose_pictures_do_not_fit_keeps_its_result_line(
    one_brick: Path, reference: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    first_trials_of(reference, out, 1)
    result = run_limited(eval_args(one_brick, out, "--snapshots"), OTHER_FILES_BYTES)
    assert_clean_error(result, str(out / "snapshots" / "trial_001"), "File too large")
    assert "2 finished trials kept" in result.stderr
    assert lines_of(out) == lines_of(reference)[:2]


def unshare_mount_works() -> bool:
    """Whether this user may mount a tmpfs in a user namespace of its own (with 4 KiB pages,
    which the test counts on)."""
    if shutil.which("unshare") is None or os.sysconf("SC_PAGE_SIZE") != 4096:
        return False
    probe = subprocess.run(
        ["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=4k tmpfs /mnt"],
        capture_output=True,
    )
    return probe.returncode == 0


@pytest.mark.slow
@pytest.mark.skipif(not unshare_mount_works(), reason="no user namespaces to mount a tmpfs")
def test_a_full_disk_ends_the_run_in_one_line_naming_it(
    one_brick: Path, reference: Path, tmp_path: Path
) -> None:
    """A 16 KiB tmpfs (four pages), mounted in a user namespace (no root needed), holding a
    run whose results.jsonl fills its first page: the next line needs a page the disk has
    not got, is written in part, and cut back."""
    lines = lines_of(reference)
    kept = next(k for k in range(len(lines)) if len(b"".join(lines[: k + 1])) > 4096)
    disk, saved = tmp_path / "disk", tmp_path / "saved"
    disk.mkdir()
    first_trials_of(reference, tmp_path / "start", kept)
    run = disk / "run"
    command = shlex.join(
        [sys.executable, "-m", "actionreasoning", *eval_args(one_brick, run, trials=kept + 1)]
    )
    q_disk, q_run = shlex.quote(str(disk)), shlex.quote(str(run))
    q_start, q_saved = shlex.quote(str(tmp_path / "start")), shlex.quote(str(saved))
    script = (
        f"mount -t tmpfs -o size=16k tmpfs {q_disk} || exit 99; "
        f"cp -r {q_start} {q_run} && echo x > {q_run}/run.lock; "  # the lock file's page
        f"dd if=/dev/zero of={q_disk}/filler bs=4096 2>/dev/null; "  # and the disk is full
        f"{command}; rc=$?; cp -r {q_run} {q_saved}; exit $rc"
    )
    result = subprocess.run(
        ["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=600
    )
    assert_clean_error(
        result, f"{run / 'results.jsonl'}: No space left on device", f"disk mounted at {disk}"
    )
    assert lines_of(saved) == lines[:kept]


# 7. hand-edited result lines


@pytest.mark.slow
def test_a_whole_last_line_without_its_newline_is_kept_by_eval_and_report(
    one_brick: Path, reference: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    first_trials_of(reference, out, 2)
    whole = (out / "results.jsonl").read_bytes()
    (out / "results.jsonl").write_bytes(whole.rstrip(b"\n"))
    shown = cli("report", str(out), "--out", str(tmp_path / "report"))
    assert shown.returncode == 0, shown.stderr
    successes = sum(json.loads(line)["success"] for line in lines_of(reference)[:2])
    assert f"{successes}/2 ok" in shown.stdout
    resumed = cli(*eval_args(one_brick, out))
    assert resumed.returncode == 0, resumed.stderr
    assert "resuming: 2 of 2 trials" in resumed.stdout
    assert (out / "results.jsonl").read_bytes() == whole


@pytest.mark.slow
@pytest.mark.parametrize("edited", [-1, 1, 5])
def test_an_edited_trial_index_is_refused_naming_the_line(
    one_brick: Path, reference: Path, tmp_path: Path, edited: int
) -> None:
    out = tmp_path / "run"
    first_trials_of(reference, out, 0)
    line0, line1 = lines_of(reference)[:2]
    copy = json.loads(line1)
    copy["trial"] = edited  # a third line: trial 1 copied, or trial 1 renumbered
    (out / "results.jsonl").write_bytes(line0 + line1 + json.dumps(copy).encode() + b"\n")
    where = f"{out / 'results.jsonl'} line 3"
    assert_clean_error(cli(*eval_args(one_brick, out, trials=3)), where)
    assert_clean_error(cli("report", str(out), "--out", str(tmp_path / "report")), where)
