"""An API key never leaves the process: not in results, transcripts, recordings, summaries,
reports or anything printed, even from a server that echoes it back in answers and errors.
Nor do the credentials of a base URL (its user name, its password or its query values) or
the value of an extra header."""

from __future__ import annotations

import base64
from pathlib import Path

import pytest
from conftest import assert_clean_error, cli
from test_llm_faults import FaultServer, fault_server, run_eval

from actionreasoning.reasoners.credentials import HEADERS_VARIABLE

__all__ = ["fault_server"]  # the fixture, shared with the fault tests

KEY = "sk-test-3f9a1c7e5b2d4a6f8e0c1b3d5f7a9e2c"
PASSWORD = "hunter2-base-url-password"
TOKEN = "tok-5e8b2f0a9c7d4e1b"
GATEWAY = "gw-2d9f4b7a1c8e3f60"  # a gateway's header, which the echo server echoes too
#: Where a base URL carries a credential; the server echoes the Authorization header
#: (HTTP Basic for user info, else the key as Bearer) and the request path with its query.
#: Each: the URL, the secret in it, and the user info the client sends as HTTP Basic.
CREDENTIALS = {
    "password": ("http://user:{password}@{host}:{port}/v1", PASSWORD, f"user:{PASSWORD}"),
    "user name": ("http://{token}@{host}:{port}/v1", TOKEN, f"{TOKEN}:"),
    "query": ("http://{host}:{port}/v1?key={token}&api-version=2024-06-01", TOKEN, None),
}


@pytest.fixture
def key(monkeypatch: pytest.MonkeyPatch) -> str:
    """The API key and a gateway's header in the environment; the key."""
    monkeypatch.setenv("OPENAI_API_KEY", KEY)
    monkeypatch.setenv(HEADERS_VARIABLE, f'{{"X-Gateway-Key": "{GATEWAY}"}}')
    return KEY


def written(root: Path) -> str:
    """Every file under ``root``, as text."""
    return "\n".join(
        path.read_bytes().decode("utf-8", "replace") for path in root.rglob("*") if path.is_file()
    )


@pytest.mark.parametrize("where", CREDENTIALS)
@pytest.mark.parametrize("fault_server", ["echo", "echo_refuse"], indirect=True)
def test_a_known_key_appears_in_no_file_and_no_output(
    tmp_path: Path,
    fault_server: FaultServer,
    key: str,
    where: str,
    capfd: pytest.CaptureFixture[str],
) -> None:
    host, port = fault_server.server_address[:2]
    template, secret, basic = CREDENTIALS[where]
    url = template.format(password=PASSWORD, token=TOKEN, host=host, port=port)
    record = tmp_path / "recording.jsonl"
    printed = []
    run = run_eval(tmp_path, fault_server, "--record", str(record), url=url)
    printed.append(run.stdout + run.stderr)
    assert "Traceback" not in printed[0]
    if fault_server.fault == "echo":
        assert run.returncode == 0, run.stderr
        assert "you sent " in record.read_text() and "[redacted]" in record.read_text()
        report = cli("report", str(tmp_path / "out"), "--out", str(tmp_path / "report"))
        assert report.returncode == 0, report.stderr
        printed.append(report.stdout + report.stderr)
    else:
        assert run.returncode == 2 and "refused every request" in run.stderr
        assert "[redacted]" in run.stderr
    check = cli("llm", "check", "--llm", "openai:m", "--base-url", url, "--llm-timeout", "2")
    printed.append(check.stdout + check.stderr)
    assert "Traceback" not in printed[-1]
    printed.append("".join(capfd.readouterr()))  # anything written past the commands' streams
    everything = written(tmp_path) + "\n".join(printed)
    assert fault_server.agent_requests or fault_server.fault == "echo_refuse"
    secrets = [KEY, KEY[-12:], secret, secret[-8:], GATEWAY, GATEWAY[-8:]]
    if basic:
        secrets.append(base64.b64encode(basic.encode()).decode())
    for text in secrets:
        assert text not in everything


def test_an_empty_base_url_is_refused_not_sent_to_the_public_api(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "out"
    commands = (["llm", "check"], ["eval", "--trials", "1", "--out", str(out)])
    for command in commands:
        assert_clean_error(cli(*command, "--llm", "openai:x", "--base-url", ""), "--base-url")
    assert not out.exists()
    monkeypatch.setenv("OPENAI_BASE_URL", "")  # an unset variable exported
    for command in commands:
        assert_clean_error(cli(*command, "--llm", "openai:x"), "OPENAI_BASE_URL")
    assert not (out / "run.json").exists()  # refused before the run directory is written
