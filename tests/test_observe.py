"""``eval --observe both|image``: every agent call carries the cameras' pictures, through
the real chat path (the prompt-only reference model over HTTP), counted as image bytes
beside the tokens, named in the transcripts, recorded once each and replayed byte for byte;
looking changes nothing in the trial, and a resume refuses another observation. In the
image tier the reference builds from the pictures alone."""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import SMALL_PATTERN, assert_clean_error, cli

from actionreasoning.reasoners.reference_server import ReferenceServer
from actionreasoning.world.pictures import SHOWN_NAMES

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def server() -> Iterator[ReferenceServer]:
    running = ReferenceServer(port=0)
    thread = threading.Thread(target=running.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield running
    running.shutdown()
    running.server_close()


@pytest.fixture(scope="module")
def pattern(tmp_path_factory: pytest.TempPathFactory) -> str:
    path = tmp_path_factory.mktemp("pattern") / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return str(path)


def run(out: Path, pattern: str, *options: str) -> dict[str, object]:
    """One trial of eval (seed 3) with ``options``; its results line."""
    args = ("eval", "--pattern", pattern, "--seed", "3", "--trials", "1", "--out", str(out))
    result = cli(*args, *options)
    assert result.returncode == 0, result.stderr
    line: dict[str, object] = json.loads((out / "results.jsonl").read_text())
    return line


def test_pictures_go_over_http_counted_named_recorded_and_replayed(
    server: ReferenceServer, pattern: str, tmp_path: Path
) -> None:
    record = tmp_path / "recording.jsonl"
    http = ("--llm", "openai:reference", "--base-url", server.url)
    line = run(
        tmp_path / "http", pattern, *http, "--observe", "both", "--record", str(record),
        "--transcripts",
    )  # fmt: skip
    assert line["success"] and line["observe"] == "both"
    transcript = tmp_path / "http" / "transcripts" / "trial_000.jsonl"
    calls = [json.loads(text) for text in transcript.read_text().splitlines()]
    assert calls and all(
        [p["name"] for p in call["pictures"]] == list(SHOWN_NAMES) for call in calls
    )
    # Each completion is sent the prompt's pictures again: bytes x completions, per brick.
    sent = [sum(p["bytes"] for p in call["pictures"]) * call["usage"]["calls"] for call in calls]
    usage = line["llm_usage"]
    assert isinstance(usage, dict) and usage["image_bytes"] == sum(sent) > 0
    bricks = line["bricks"]
    assert isinstance(bricks, list)
    assert sum(brick["llm_usage"]["image_bytes"] for brick in bricks) == usage["image_bytes"]
    # Each picture is stored once, under the hash the transcripts name it by.
    stored = [json.loads(text) for text in record.read_text().splitlines()]
    hashes = [r["sha256"] for r in stored if r["kind"] == "image"]
    named = {p["sha256"] for call in calls for p in call["pictures"]}
    assert len(hashes) == len(set(hashes)) and set(hashes) == named
    run(tmp_path / "replay", pattern, "--llm", f"replay:{record}", "--observe", "both")
    lines = [(tmp_path / name / "results.jsonl").read_bytes() for name in ("http", "replay")]
    assert lines[0] == lines[1]


def test_looking_changes_nothing_and_a_resume_keeps_the_observation(
    pattern: str, tmp_path: Path
) -> None:
    """The built-in reasoner reads the state either way: rendering the pictures leaves the
    trial as it was, to the bit; only the line's ``observe`` and ``perception`` (how far
    the answers' poses of bricks were from them, measured with pictures) tell them apart."""
    state = run(tmp_path / "state", pattern)
    both = run(tmp_path / "both", pattern, "--observe", "both")
    assert "observe" not in state and both.pop("observe") == "both"
    assert "perception" not in state and set(both.pop("perception")) == {"pre_grasp", "descent"}
    assert both == state
    resumed = cli(
        "eval", "--pattern", pattern, "--seed", "3", "--trials", "2",
        "--out", str(tmp_path / "both"),
    )  # fmt: skip
    assert_clean_error(resumed, "holds a different run", "observe")


@pytest.mark.parametrize("tools", ["check", "none"])
def test_the_reference_builds_from_the_pictures_alone_over_http(
    server: ReferenceServer, pattern: str, tmp_path: Path, tools: str
) -> None:
    """observe "image": the prompt-only reference model reads the bricks from the pictures
    its requests carry (the state block shows none) and builds the pattern with no
    fallback; agent 1 names no brick id, and the line records how far the answers' poses
    of bricks were from them. A replay of its recording writes the same line."""
    http = ("--llm", "openai:reference", "--base-url", server.url, "--tools", tools)
    record = ("--record", str(tmp_path / "recording.jsonl"))
    line = run(tmp_path / "image", pattern, *http, "--observe", "image", "--transcripts", *record)
    assert line["success"] and line["observe"] == "image" and line["fallback_decisions"] == 0
    transcript = tmp_path / "image" / "transcripts" / "trial_000.jsonl"
    calls = [json.loads(text) for text in transcript.read_text().splitlines()]
    first = [call for call in calls if call["agent"] == "pre_grasp"]
    assert first and all("brick_id" not in call["answer"] for call in first)
    assert all(call["brick"] is not None for call in first)  # named by where it lies
    perception = line["perception"]
    assert isinstance(perception, dict) and set(perception) == {"pre_grasp", "descent"}
    for errors in perception.values():
        assert errors["answers"] >= 3 and errors["centre_offset_cm_max"] < 0.5
        assert errors["yaw_error_deg_max"] < 0.5
    replay = ("--llm", f"replay:{record[1]}", "--tools", tools, "--observe", "image")
    run(tmp_path / "replay", pattern, *replay)
    lines = [(tmp_path / name / "results.jsonl").read_bytes() for name in ("image", "replay")]
    assert lines[0] == lines[1]
