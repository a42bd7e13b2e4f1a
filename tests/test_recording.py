"""A recording given to replay that is not one (binary, a bad header, an exchange without
its usage) is refused in one line; a label with rich markup in it is printed as text."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import assert_clean_error, cli

from actionreasoning.agents.outputs import GraspAnswer
from actionreasoning.reasoners.chat import ChatRequest
from actionreasoning.reasoners.factory import CHECK_PROMPT
from actionreasoning.reasoners.recording import request_key

HEADER = {"kind": "header", "llm": "openai:m", "mode": "json_schema"}
CHECK = ChatRequest(
    messages=({"role": "user", "content": CHECK_PROMPT},),
    schema_name="grasp",
    schema=GraspAnswer.model_json_schema(),
)
EXCHANGE = {
    "kind": "exchange",
    "key": request_key(CHECK),
    "request": {"messages": list(CHECK.messages), "name": "grasp"},
    "content": '{"close": true, "rationale": "ok"}',
    "usage": {"calls": 1, "prompt_tokens": 3, "completion_tokens": 4, "latency_s": 0.5},
}


def lines(*records: object) -> bytes:
    return b"".join(json.dumps(record).encode() + b"\n" for record in records)


@pytest.mark.parametrize(
    ("content", "named"),
    [
        (bytes(range(256)) * 4, "line 1"),
        (b"", "no header"),
        (lines({**HEADER, "mode": "telepathy"}), "line 1"),
        (lines({k: v for k, v in HEADER.items() if k != "llm"}), "line 1"),
        (lines(EXCHANGE), "line 1"),
        (lines(HEADER, {k: v for k, v in EXCHANGE.items() if k != "usage"}), "line 2"),
        (lines(HEADER, {**EXCHANGE, "usage": {"calls": "many"}}), "line 2"),
        (lines(HEADER, [1, 2]), "line 2"),
        (lines(HEADER) + b"[" * 100_000 + b"\n", "line 2"),
    ],
    ids=["binary", "empty", "bad mode", "no llm", "no header", "no usage", "bad usage",
         "not an object", "deep"],
)  # fmt: skip
def test_a_broken_recording_is_refused_in_one_line(
    tmp_path: Path, content: bytes, named: str
) -> None:
    recording = tmp_path / "recording.jsonl"
    recording.write_bytes(content)
    for command in (["llm", "check"], ["eval", "--trials", "1", "--out", str(tmp_path / "out")]):
        result = cli(*command, "--llm", f"replay:{recording}")
        assert_clean_error(result, str(recording), named)


def test_a_recorded_label_with_markup_is_printed_as_text(tmp_path: Path) -> None:
    recording = tmp_path / "recording.jsonl"
    recording.write_bytes(lines({**HEADER, "llm": "openai:[/]x[bold"}, EXCHANGE))
    result = cli("llm", "check", "--llm", f"replay:{recording}")
    assert result.returncode == 0, result.stderr
    assert "llm check openai:[/]x[bold" in result.stdout
