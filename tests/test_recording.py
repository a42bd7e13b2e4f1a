"""A recording given to replay that is not one (binary, a bad header, an exchange without
its usage) is refused in one line; a label with rich markup in it is printed as text; the
pictures requests carried are stored once each and replayed."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, cli

from actionreasoning.agents.outputs import GraspAnswer
from actionreasoning.reasoners.chat import ChatRequest, StructuredMode, image_urls, user_message
from actionreasoning.reasoners.factory import CHECK_PROMPT
from actionreasoning.reasoners.recording import RecordingChat, ReplayChat, request_key
from actionreasoning.world.pictures import Picture, PictureKind, depth_png

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


def test_pictures_are_recorded_once_under_their_hash_and_replayed(tmp_path: Path) -> None:
    """Two requests carrying the same two pictures (one of them twice) store each picture
    once, named by the hash of its bytes as transcripts name it; the exchanges name them
    ``sha256:HASH`` and replay serves them; recording on into the file stores none again."""
    pictures = [
        Picture("top_down", PictureKind.DEPTH, depth_png(np.full((4, 4), depth)))
        for depth in (1.0, 2.0)
    ]
    request = ChatRequest(
        messages=(
            user_message("look", pictures),
            {"role": "assistant", "content": "{}"},
            user_message("again", pictures[:1]),
        ),
        schema_name="grasp",
        schema=GraspAnswer.model_json_schema(),
    )
    source = tmp_path / "source.jsonl"
    exchange = {**EXCHANGE, "key": request_key(request)}
    source.write_bytes(lines(HEADER, *[exchange] * 4))
    copy = tmp_path / "copy.jsonl"
    for _ in range(2):  # the second time into the file it has
        recorder = RecordingChat(ReplayChat(source), copy, StructuredMode.JSON_SCHEMA)
        for _ in range(2):
            assert recorder.complete(request).content == EXCHANGE["content"]
    records = [json.loads(line) for line in copy.read_text().splitlines()]
    stored = [r for r in records if r["kind"] == "image"]
    assert [r["sha256"] for r in stored] == [p.sha256 for p in pictures]
    assert [r["url"] for r in stored] == [p.data_url for p in pictures]
    exchanges = [r for r in records if r["kind"] == "exchange"]
    assert len(exchanges) == 4 and all("base64" not in json.dumps(r) for r in exchanges)
    assert image_urls(exchanges[0]["request"]["messages"][0]) == [
        f"sha256:{p.sha256}" for p in pictures
    ]
    replay = ReplayChat(copy)
    assert [replay.complete(request).content for _ in range(4)] == [EXCHANGE["content"]] * 4
