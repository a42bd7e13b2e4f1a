"""Evaluation at scale, as a user runs it: worker processes, a Ray cluster, SIGKILL and
resume; each compared line for line with a serial run of the same seeds."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import (
    SMALL_PATTERN,
    assert_clean_error,
    assert_processes_end,
    children,
    cli,
    cli_process,
    free_port,
)

TRIALS = "3"


@pytest.fixture(scope="module")
def pattern(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("pattern") / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return path


def eval_args(pattern: Path, out: Path, *extra: str) -> list[str]:
    return [
        "eval", "--method", "classical", "--pattern", str(pattern), "--trials", TRIALS,
        "--seed", "5", "--out", str(out), "--physics", "precise", *extra,
    ]  # fmt: skip


def sorted_lines(out: Path) -> list[str]:
    lines = (out / "results.jsonl").read_text().splitlines()
    return sorted(lines, key=lambda line: json.loads(line)["trial"])


@pytest.fixture(scope="module")
def serial(pattern: Path, tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    """The reference: the trials one after another in one process."""
    out = tmp_path_factory.mktemp("serial") / "run"
    result = cli(*eval_args(pattern, out))
    assert result.returncode == 0, result.stderr
    lines = sorted_lines(out)
    assert [json.loads(line)["trial"] for line in lines] == [0, 1, 2]
    return lines


@pytest.mark.slow
def test_two_workers_give_the_serial_results(
    pattern: Path, serial: list[str], tmp_path: Path
) -> None:
    result = cli_process(*eval_args(pattern, tmp_path / "run", "--workers", "2"))
    assert result.returncode == 0, result.stderr
    assert sorted_lines(tmp_path / "run") == serial
    # Not a terminal: one plain line per finished trial, with the count and successes so far.
    assert "[3/3, 3 ok] trial" in result.stdout


@pytest.mark.slow
def test_a_run_killed_with_sigkill_resumes_without_loss_or_duplicates(
    pattern: Path, serial: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "run"
    command = [sys.executable, "-m", "actionreasoning", *eval_args(pattern, out)]
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    results = out / "results.jsonl"
    deadline = time.monotonic() + 300
    while not (results.exists() and results.read_text().count("\n") >= 1):
        assert process.poll() is None and time.monotonic() < deadline, "no trial finished"
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    finished = sorted_lines(out)
    assert 1 <= len(finished) < 3 and finished == serial[: len(finished)]

    resumed = cli(*eval_args(pattern, out))
    assert resumed.returncode == 0, resumed.stderr
    assert f"resuming: {len(finished)} of 3 trials" in resumed.stdout
    assert sorted_lines(out) == serial
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == 3 and summary["resumed_trials"] == len(finished)

    again = cli(*eval_args(pattern, out))
    assert again.returncode == 0 and "resuming: 3 of 3" in again.stdout
    assert sorted_lines(out) == serial


@pytest.mark.slow
@pytest.mark.parametrize("stop", [signal.SIGTERM, signal.SIGKILL], ids=lambda s: s.name)
def test_a_run_with_workers_stopped_by_a_signal_prints_no_warning_and_keeps_its_trials(
    pattern: Path, serial: list[str], tmp_path: Path, stop: signal.Signals
) -> None:
    """SIGTERM stops the run as Ctrl-C does; after SIGKILL, multiprocessing's resource
    tracker frees the workers' semaphores without warning about it (it used to, either way)."""
    out = tmp_path / "run"
    command = [sys.executable, "-m", "actionreasoning", *eval_args(pattern, out, "--workers", "2")]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    results = out / "results.jsonl"
    deadline = time.monotonic() + 300
    while not (results.exists() and results.read_text().count("\n") >= 1):
        assert process.poll() is None and time.monotonic() < deadline, "no trial finished"
        time.sleep(0.05)
    workers = children(process.pid)
    process.send_signal(stop)
    _, stderr = process.communicate(timeout=120)  # until every process holding stderr ends
    assert_processes_end(workers, "the workers")
    if stop is signal.SIGTERM:
        assert process.returncode == 130
        assert (
            stderr
            == "interrupted: the finished trials are saved: run the same command to run the rest\n"
        )
    else:
        assert process.returncode == -signal.SIGKILL and stderr == ""
    finished = sorted_lines(out)
    assert finished and set(finished) <= set(serial) and len(set(finished)) == len(finished)


def ray_env() -> dict[str, str]:
    """The environment of the test's Ray cluster and its client, with Ray's token
    authentication off whatever the user's Ray state: a token left in ~/.ray/auth_token (by
    an earlier local ``ray.init``) turns it on for ``ray start`` but not for a client given
    the cluster's address, which the cluster then refuses (InvalidAuthToken)."""
    return {**os.environ, "RAY_AUTH_MODE": "disabled"}


@pytest.fixture(scope="module")
def ray_cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A real local Ray head node, started as a user would, stopped afterwards."""
    ray = shutil.which("ray", path=str(Path(sys.executable).parent))
    assert ray is not None, "the test extras install ray"
    port = free_port()
    temp = tmp_path_factory.mktemp("ray")
    start = subprocess.run(
        [ray, "start", "--head", f"--port={port}", "--num-cpus=2", "--include-dashboard=false",
         "--disable-usage-stats", f"--temp-dir={temp}"],
        capture_output=True, text=True, timeout=180, env=ray_env(),
    )  # fmt: skip
    assert start.returncode == 0, start.stderr
    try:
        yield f"127.0.0.1:{port}"
    finally:
        subprocess.run([ray, "stop", "--force"], capture_output=True, timeout=120)


@pytest.mark.slow
def test_trials_on_a_local_ray_cluster_give_the_serial_results_recordings_and_videos(
    pattern: Path, serial: list[str], ray_cluster: str, tmp_path: Path
) -> None:
    args = eval_args(pattern, tmp_path / "run", "--ray", ray_cluster, "--rerun", "--video")
    result = cli_process(*args, env=ray_env())
    assert result.returncode == 0, result.stderr
    assert sorted_lines(tmp_path / "run") == serial
    # The recordings and videos come back from the tasks with their results.
    recordings = sorted(p.name for p in (tmp_path / "run" / "rerun").glob("*.rrd"))
    assert recordings == ["trial_000.rrd", "trial_001.rrd", "trial_002.rrd"]
    videos = sorted(p.read_bytes()[4:8] for p in (tmp_path / "run" / "videos").glob("*.mp4"))
    assert videos == [b"ftyp"] * 3


@pytest.mark.slow  # starts a Ray client in a process of its own, as the other Ray tests
def test_a_ray_address_where_nothing_listens_is_refused_at_once(
    pattern: Path, tmp_path: Path
) -> None:
    address = f"127.0.0.1:{free_port()}"
    # In a process of its own: Ray keeps global state in the process that calls it.
    result = cli_process(*eval_args(pattern, tmp_path / "run", "--ray", address), timeout=60)
    assert_clean_error(result, f"--ray {address}: no Ray cluster answers there")


@pytest.mark.parametrize(
    ("extra", "needle"),
    [
        (("--workers", "2", "--ray", "auto"), "--workers and --ray exclude each other"),
        (
            ("--method", "agents", "--llm", "openai:m", "--record", "r.jsonl", "--workers", "2"),
            "--record writes one file from one process",
        ),
    ],
)
def test_engine_options_that_cannot_work_together_are_refused(
    pattern: Path, tmp_path: Path, extra: tuple[str, ...], needle: str
) -> None:
    assert_clean_error(cli(*eval_args(pattern, tmp_path / "run", *extra)), needle)


@pytest.mark.slow
def test_ctrl_c_stops_workers_at_once_and_keeps_whole_lines(
    pattern: Path, serial: list[str], tmp_path: Path
) -> None:
    out = tmp_path / "run"
    # Twice the reference's trials: work is still in flight when the first line lands,
    # however the trials' durations fall.
    args = eval_args(pattern, out, "--workers", "2")
    args[args.index("--trials") + 1] = str(2 * int(TRIALS))
    command = [sys.executable, "-m", "actionreasoning", *args]
    # As from a terminal: Ctrl-C at its default in the child, whatever an earlier test left
    # in this process (an ignored SIGINT would be inherited, and the run would finish).
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    results = out / "results.jsonl"
    deadline = time.monotonic() + 300
    while not (results.exists() and results.read_text().count("\n") >= 1):
        assert process.poll() is None and time.monotonic() < deadline, "no trial finished"
        time.sleep(0.05)
    process.send_signal(signal.SIGINT)  # to the main process only, as a terminal's Ctrl-C
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130, stderr
    assert stderr.strip() == (
        "interrupted: the finished trials are saved: run the same command to run the rest"
    )
    finished = sorted_lines(out)
    assert 0 < len(finished) < 2 * int(TRIALS)
    assert {line for line in finished if json.loads(line)["trial"] < int(TRIALS)} <= set(serial)


@pytest.mark.slow
def test_workers_end_when_their_run_is_killed(pattern: Path, tmp_path: Path) -> None:
    command = [sys.executable, "-m", "actionreasoning", *eval_args(pattern, tmp_path / "run")]
    process = subprocess.Popen(
        [*command, "--workers", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.monotonic() + 120
    while len(workers := children(process.pid)) < 2:
        assert process.poll() is None and time.monotonic() < deadline, "no workers started"
        time.sleep(0.05)
    time.sleep(2.0)  # into their first trials
    process.kill()
    process.wait()
    assert_processes_end(workers, "workers")
