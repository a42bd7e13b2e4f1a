"""An API key never leaves the process: not in results, transcripts, recordings, summaries,
reports or anything printed, even from a server that echoes it back in answers and errors."""

from __future__ import annotations

import base64
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_llm_faults import FaultServer, fault_server, run_eval

__all__ = ["fault_server"]  # the fixture, shared with the fault tests

KEY = "sk-test-3f9a1c7e5b2d4a6f8e0c1b3d5f7a9e2c"
PASSWORD = "hunter2-base-url-password"


@pytest.fixture
def key(monkeypatch: pytest.MonkeyPatch) -> str:
    monkeypatch.setenv("OPENAI_API_KEY", KEY)
    return KEY


def written(root: Path) -> str:
    """Every file under ``root``, as text."""
    return "\n".join(
        path.read_bytes().decode("utf-8", "replace") for path in root.rglob("*") if path.is_file()
    )


@pytest.mark.parametrize("fault_server", ["echo", "echo_refuse"], indirect=True)
def test_a_known_key_appears_in_no_file_and_no_output(
    tmp_path: Path, fault_server: FaultServer, key: str
) -> None:
    host, port = fault_server.server_address[:2]
    url = f"http://user:{PASSWORD}@{host}:{port}/v1"  # sent as HTTP Basic, not the key
    record = tmp_path / "recording.jsonl"
    printed = []
    run = run_eval(tmp_path, fault_server, "--record", str(record))  # the key as Bearer
    printed.append(run.stdout + run.stderr)
    assert "Traceback" not in printed[0]
    if fault_server.fault == "echo":
        assert run.returncode == 0, run.stderr
        assert "you sent Bearer [redacted] from" in record.read_text()
        report = subprocess.run(
            [sys.executable, "-m", "actionreasoning", "report", str(tmp_path / "out"),
             "--out", str(tmp_path / "report")],
            capture_output=True, text=True, timeout=120,
        )  # fmt: skip
        assert report.returncode == 0, report.stderr
        printed.append(report.stdout + report.stderr)
    else:
        assert run.returncode == 2 and "refused every request" in run.stderr
        assert "[redacted]" in run.stderr
    check = subprocess.run(
        [sys.executable, "-m", "actionreasoning", "llm", "check", "--llm", "openai:m",
         "--base-url", url, "--llm-timeout", "2"],
        capture_output=True, text=True, timeout=120, env=os.environ,
    )  # fmt: skip
    printed.append(check.stdout + check.stderr)
    everything = written(tmp_path) + "\n".join(printed)
    assert fault_server.agent_requests or fault_server.fault == "echo_refuse"
    basic = base64.b64encode(f"user:{PASSWORD}".encode()).decode()
    for secret in (KEY, KEY[-12:], PASSWORD, basic):
        assert secret not in everything
