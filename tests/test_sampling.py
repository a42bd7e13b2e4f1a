"""Sampling settings and gateway headers: what is given reaches every request, as the
prompt-only reference server receives it; run.json and a recording's header record the
settings and the header names, never a header's value; a resume or a replay under other
settings is refused naming them; bad values are refused naming the option."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from conftest import assert_clean_error, cli
from test_llm_faults import ONE_BRICK

from actionreasoning.reasoners.credentials import HEADERS_VARIABLE
from actionreasoning.reasoners.reference_server import ReferenceServer, _Handler

SECRET = "gw-7c1e9a4f2b8d6e0a"
HEADERS = {"X-Title": "sampling test", "X-Gateway-Key": SECRET}
KNOBS = (
    "--temperature", "0.7", "--top-p", "0.9", "--max-tokens", "400", "--llm-seed", "5",
    "--reasoning-effort", "high",
)  # fmt: skip
#: What run.json and the recording's header hold of KNOBS.
RECORDED = dict(temperature=0.7, top_p=0.9, max_tokens=400, seed=5, reasoning_effort="high")


class Received(_Handler):
    """The reference server's handler, keeping each request's body and headers (names in
    lower case)."""

    def _body(self) -> dict[str, Any]:
        body = super()._body()
        headers = {name.lower(): value for name, value in self.headers.items()}
        self.server.received.append((body, headers))  # type: ignore[attr-defined]
        return body


@pytest.fixture(scope="module")
def server() -> Iterator[ReferenceServer]:
    """The reference model's server on loopback; ``received`` holds (body, headers) of
    every chat request."""
    served = ReferenceServer(port=0)
    served.RequestHandlerClass = Received
    served.received = []  # type: ignore[attr-defined]
    thread = threading.Thread(target=served.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield served
    served.shutdown()
    served.server_close()


@dataclass(frozen=True)
class Run:
    root: Path
    requests: list[tuple[dict[str, Any], dict[str, str]]]
    printed: str

    @property
    def out(self) -> Path:
        return self.root / "out"

    @property
    def recording(self) -> Path:
        return self.root / "recording.jsonl"


def evaluate(out: Path, llm: str, *extra: str) -> Any:
    """One trial of the one-brick pattern, whose file is next to ``out``."""
    pattern = out.parent / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    return cli(
        "eval", "--pattern", str(pattern), "--trials", "1", "--seed", "2", "--out", str(out),
        "--llm", llm, *extra,
    )  # fmt: skip


@pytest.fixture(scope="module")
def knob_run(server: ReferenceServer, tmp_path_factory: pytest.TempPathFactory) -> Run:
    """One recorded one-brick trial with every setting given and two extra headers."""
    root = tmp_path_factory.mktemp("knobs")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(HEADERS_VARIABLE, json.dumps(HEADERS))
        start = len(server.received)  # type: ignore[attr-defined]
        result = evaluate(
            root / "out", "openai:reference", "--base-url", server.url, *KNOBS,
            "--record", str(root / "recording.jsonl"), "--transcripts",
        )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return Run(root, server.received[start:], result.stdout + result.stderr)  # type: ignore[attr-defined]


@pytest.mark.slow
def test_every_request_carries_the_settings_and_the_headers(knob_run: Run) -> None:
    probe, *asked = knob_run.requests
    assert asked and json.loads(knob_run.out.joinpath("results.jsonl").read_text())["success"]
    for body, headers in knob_run.requests:
        assert body["temperature"] == 0.7 and body["top_p"] == 0.9 and body["seed"] == 5
        assert body["reasoning_effort"] == "high"
        assert "max_tokens" not in body  # with a reasoning effort, the cap reasoning models take
        assert headers["x-title"] == "sampling test" and headers["x-gateway-key"] == SECRET
    assert probe[0]["max_completion_tokens"] == 20  # the structured-output probe's own cap
    assert {body["max_completion_tokens"] for body, _ in asked} == {400}


@pytest.mark.slow
def test_run_json_and_the_recording_hold_the_settings_and_header_names_only(
    knob_run: Run,
) -> None:
    llm = json.loads((knob_run.out / "run.json").read_text())["config"]["llm"]
    assert llm["sampling"] == RECORDED
    assert llm["headers"] == ["X-Gateway-Key", "X-Title"]
    header = json.loads(knob_run.recording.read_text().splitlines()[0])
    assert header["sampling"] == RECORDED
    written = [path.read_text() for path in knob_run.root.rglob("*") if path.is_file()]
    assert not any(SECRET in text for text in [*written, knob_run.printed])


@pytest.mark.slow
def test_a_resume_under_other_settings_or_headers_is_refused_naming_them(
    knob_run: Run, server: ReferenceServer, monkeypatch: pytest.MonkeyPatch
) -> None:
    lines = (knob_run.out / "results.jsonl").read_bytes()
    args = ("openai:reference", "--base-url", server.url, "--record", str(knob_run.recording))
    monkeypatch.setenv(HEADERS_VARIABLE, json.dumps(HEADERS))
    hotter = [*KNOBS[:1], "1.0", *KNOBS[2:]]
    refused = evaluate(knob_run.out, *args, *hotter)
    assert_clean_error(refused, "llm.sampling.temperature 0.7 there, 1.0 now")
    refused = evaluate(knob_run.out, *args, *KNOBS[2:])  # the default temperature
    assert_clean_error(refused, "llm.sampling.temperature 0.7 there, None now")
    monkeypatch.setenv(HEADERS_VARIABLE, json.dumps({"X-Title": "sampling test"}))
    refused = evaluate(knob_run.out, *args, *KNOBS)
    assert_clean_error(refused, "llm.headers ['X-Gateway-Key', 'X-Title'] there")
    monkeypatch.setenv(HEADERS_VARIABLE, json.dumps(HEADERS))
    resumed = evaluate(knob_run.out, *args, *KNOBS)
    assert resumed.returncode == 0, resumed.stderr
    assert (knob_run.out / "results.jsonl").read_bytes() == lines  # nothing ran again


@pytest.mark.slow
def test_a_replay_gives_the_recorded_line_under_the_recorded_settings(knob_run: Run) -> None:
    replay = knob_run.root / "replay"
    result = evaluate(replay, f"replay:{knob_run.recording}")
    assert result.returncode == 0, result.stderr
    recorded = (knob_run.out / "results.jsonl").read_text()
    assert (replay / "results.jsonl").read_text() == recorded
    llm = json.loads((replay / "run.json").read_text())["config"]["llm"]
    assert llm["sampling"] == RECORDED
    same = evaluate(knob_run.root / "again", f"replay:{knob_run.recording}", *KNOBS)
    assert same.returncode == 0, same.stderr  # the recorded settings may be repeated
    other = evaluate(replay, f"replay:{knob_run.recording}", "--temperature", "0.2")
    assert_clean_error(other, "answers sampled with temperature 0.7", "drop --temperature")


@pytest.mark.slow
def test_recording_into_a_file_of_other_settings_is_refused(
    knob_run: Run, server: ReferenceServer, tmp_path: Path
) -> None:
    before = knob_run.recording.read_bytes()
    refused = evaluate(
        tmp_path / "out", "openai:reference", "--base-url", server.url, "--temperature", "0.2",
        "--record", str(knob_run.recording),
    )  # fmt: skip
    assert_clean_error(refused, "holds answers sampled with temperature 0.7", "another file")
    assert knob_run.recording.read_bytes() == before


@pytest.mark.slow
def test_the_defaults_send_what_was_always_sent_and_record_nothing_new(
    server: ReferenceServer, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(HEADERS_VARIABLE, raising=False)
    start = len(server.received)  # type: ignore[attr-defined]
    result = evaluate(tmp_path / "out", "openai:reference", "--base-url", server.url)
    assert result.returncode == 0, result.stderr
    requests = server.received[start:]  # type: ignore[attr-defined]
    for body, headers in requests[1:]:
        sampling = {k: v for k, v in body.items() if k not in ("model", "messages")}
        sampling.pop("response_format")
        assert sampling == {"temperature": 0.0, "seed": 0, "max_tokens": 300}
        assert "x-title" not in headers
    llm = json.loads((tmp_path / "out" / "run.json").read_text())["config"]["llm"]
    assert list(llm) == ["spec", "limits", "fallback"]  # as run.json was before the settings


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--temperature", "-0.1", "--temperature -0.1: give a value from 0 to 2"),
        ("--temperature", "2.5", "--temperature 2.5: give a value from 0 to 2"),
        ("--temperature", "nan", "--temperature nan"),
        ("--top-p", "0", "--top-p 0.0: give a value above 0 and at most 1"),
        ("--top-p", "1.01", "--top-p 1.01"),
        ("--max-tokens", "0", "--max-tokens 0: give at least 1"),
        ("--llm-seed", "-1", "--llm-seed -1"),
        ("--llm-seed", str(2**32), "--llm-seed 4294967296"),
    ],
)
def test_a_value_out_of_range_is_refused_naming_the_option(
    tmp_path: Path, option: str, value: str, message: str
) -> None:
    for command in (["eval", "--out", str(tmp_path / "out")], ["llm", "check"]):
        result = cli(*command, "--llm", "openai:m", option, value)
        assert_clean_error(result, message)
    assert not (tmp_path / "out").exists()


def test_an_unknown_reasoning_effort_is_refused_naming_the_choices(tmp_path: Path) -> None:
    result = cli("eval", "--out", str(tmp_path), "--llm", "openai:m", "--reasoning-effort", "max")
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert "--reasoning-effort" in result.stderr and "'low', 'medium', 'high'" in result.stderr


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--temperature", "0.5"], "--temperature: the built-in reasoner samples nothing"),
        (
            ["--method", "classical", "--llm-seed", "3", "--top-p", "0.5"],
            "--method classical uses no reasoner; drop --top-p, --llm-seed",
        ),
        (
            ["--llm", "llamacpp:model.gguf", "--reasoning-effort", "low"],
            "--reasoning-effort is for --llm openai:MODEL",
        ),
    ],
    ids=["builtin", "classical", "llamacpp"],
)
def test_settings_a_backend_would_not_use_are_refused(
    tmp_path: Path, args: list[str], message: str
) -> None:
    assert_clean_error(cli("eval", "--out", str(tmp_path / "out"), *args), message)
    assert not (tmp_path / "out" / "run.json").exists()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ("{not json", "is not a JSON object of header names to values"),
        ('["X-Title"]', "is not a JSON object of header names to values"),
        ('{"X Title": "%s"}', "header 1 has no valid HTTP name"),
        ('{"X-Title": "a", "x-title": "%s"}', "names x-title twice"),
        ('{"X-Title": "a", "X-Title": "%s"}', "names X-Title twice"),
        ('{"X-Key": " %s"}', "the value of X-Key begins or ends with a space"),
        ('{"X-Key": "%s "}', "the value of X-Key begins or ends with a space"),
        ('{"Content-Length": "%s"}', "Content-Length is written by the client itself"),
        ('{"X-Key": 7}', "the value of X-Key must be a string of printable ASCII"),
        ('{"X-Key": "%s\\r\\nX-Evil: 1"}', "the value of X-Key must be a string"),
        ('{"X-Key": "%s\\u00e9"}', "the value of X-Key must be a string"),
    ],
    ids=["not json", "not an object", "bad name", "twice", "exactly twice", "leading space",
         "trailing space", "client's", "number", "crlf", "non-ascii"],
)  # fmt: skip
def test_a_bad_header_variable_is_refused_naming_it_and_no_value(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, value: str, message: str
) -> None:
    monkeypatch.setenv(HEADERS_VARIABLE, value.replace("%s", SECRET))
    url = "http://127.0.0.1:9/v1"  # refused before any connection
    for command in (["eval", "--out", str(tmp_path / "out")], ["llm", "check"]):
        result = cli(*command, "--llm", "openai:m", "--base-url", url)
        assert_clean_error(result, HEADERS_VARIABLE, message)
        assert SECRET not in result.stderr
