"""The Inspect task ``actionreasoning/brick_stack``: found through the package's entry point,
one sample a seeded trial of ``eval``, bad options refused in one line, the agents' schemas
and tools in Inspect's terms, native tool calls in and out of the reasoner's in-band form,
and, end to end, ``inspect eval`` over the reference model's server on loopback scoring
the pyramid exactly as ``actionreasoning eval`` does (in-band and native tool calls alike).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np
import pytest
from conftest import SMALL_PATTERN, cli, free_port
from inspect_ai.log import EvalLog, read_eval_log
from inspect_ai.model import (
    ChatMessageAssistant,
    ChatMessageTool,
    ChatMessageUser,
    ContentImage,
    ContentText,
)
from inspect_ai.tool import ToolCall

from actionreasoning.agents.observation import Observation
from actionreasoning.agents.outputs import PreGraspDecision, WaypointProposal
from actionreasoning.agents.spec import agent_specs, single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.errors import ConfigError
from actionreasoning.inspect_task.conversation import chat_messages, in_band
from actionreasoning.inspect_task.options import TaskOptions
from actionreasoning.inspect_task.schemas import agent_tools, response_schema, tool_info
from actionreasoning.inspect_task.solver import RESULT
from actionreasoning.inspect_task.task import brick_stack
from actionreasoning.reasoners.chat import user_message
from actionreasoning.reasoners.llm import NO_MORE_TOOLS, TOOL_RESULTS
from actionreasoning.reasoners.reference_model import reply
from actionreasoning.reasoners.reference_server import (
    TOKENS_PER_MESSAGE,
    ReferenceServer,
    estimate_tokens,
)
from actionreasoning.trial.provenance import Provenance
from actionreasoning.trial.rules import Method, trial_seed
from actionreasoning.trial.session import Conditions
from actionreasoning.world.pictures import Picture, PictureKind, colour_png

TASK = "actionreasoning/brick_stack"
#: Two trials of the pyramid at seed 0: what the end-to-end tests run.
TRIALS = 2


def inspect(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """The ``inspect`` command in a process of its own, its output not wrapped."""
    return subprocess.run(
        [sys.executable, "-m", "inspect_ai", *args],
        capture_output=True,
        text=True,
        timeout=900,
        env={**os.environ, "COLUMNS": "1000", **(env or {})},
        check=False,
    )


def test_the_task_is_found_through_the_entry_point() -> None:
    """A fresh process: Inspect loads the package's entry point to list its tasks."""
    listed = subprocess.run(
        [
            sys.executable,
            "-c",
            "from inspect_ai._util.registry import registry_find, registry_info\n"
            "tasks = registry_find(lambda info: info.type == 'task')\n"
            "print(sorted(registry_info(t).name for t in tasks))",
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert listed.returncode == 0, listed.stderr
    assert TASK in listed.stdout


def test_its_samples_are_the_seeded_trials_of_eval() -> None:
    task = brick_stack(trials=3, seed=5)
    samples = list(task.dataset)
    assert [s.id for s in samples] == [0, 1, 2]
    assert [s.metadata for s in samples] == [
        {"trial": t, "seed": 5, "trial_seed": trial_seed(5, t)} for t in range(3)
    ]
    assert "6 bricks" in str(samples[0].input)
    conditions = Conditions.load("pyramid", "paper", "none", tools="check")
    options = TaskOptions(seed=5)
    assert options.spec(options.conditions(), 2) == conditions.spec(5, 2)
    single = TaskOptions(method="single-agent", seed=5).spec(conditions, 2)
    assert single.method is Method.SINGLE_AGENT and single.run_seed == 5 and single.trial == 2


@pytest.mark.parametrize(
    ("options", "named"),
    [
        ({"method": "classical"}, "-T method=classical"),
        ({"trials": 0}, "-T trials=0"),
        ({"seed": -1}, "-T seed=-1"),
        ({"seed": True}, "-T seed=True"),
        ({"cache": "maybe"}, "-T cache='maybe'"),
        ({"pattern": 3}, "-T pattern=3"),
        ({"physics": "moon"}, "physics profile 'moon'"),
        ({"tools": "all"}, "tools 'all'"),
        ({"pattern": "no-such-pattern.json"}, "no-such-pattern.json"),
        ({"observe": "eyes"}, "-T observe=eyes"),
        ({"method": "single-agent", "observe": "image"}, "-T observe=image"),
    ],
)
def test_bad_options_are_refused_in_one_line(options: dict[str, Any], named: str) -> None:
    with pytest.raises(ConfigError) as refused:
        brick_stack(**options)
    message = str(refused.value)
    assert named in message and "\n" not in message


def test_the_command_prints_a_refused_option_as_its_one_line() -> None:
    run = inspect("eval", TASK, "--model", "mockllm/model", "-T", "noise=loud")
    assert run.returncode != 0
    lines = [line for line in (run.stdout + run.stderr).splitlines() if line.strip()]
    assert lines == [
        "error: actionreasoning/brick_stack: unknown noise level 'loud' (known: none, low, "
        "medium, high, or a .json/.yaml file)"
    ]


def test_answers_and_tool_arguments_keep_their_schemas_in_inspects_terms() -> None:
    """Inspect's JSONSchema has no references or tuples: what the converted schemas accept
    and refuse is what the answer models do, for the answers tried here."""
    decision = PreGraspDecision(
        brick_id=0,
        target_index=1,
        waypoint=WaypointProposal(position_m=(0.5, 0.1, 0.3), quat_xyzw=(1.0, 0.0, 0.0, 0.0)),
    ).model_dump(mode="json")
    tool_turn = {"tool_calls": [{"name": "reachability", "arguments": {"brick_id": 0}}]}
    for spec in (agent_specs()[0], single_agent_spec()):
        schema = response_schema(spec.key, spec.output_model.model_json_schema())
        plain = schema.json_schema.model_dump(exclude_none=True)
        assert "$ref" not in json.dumps(plain) and "prefixItems" not in json.dumps(plain)
        for answer in (decision, tool_turn):
            jsonschema.validate(answer, plain)
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate({**decision, "waypoint": {"position_m": "above"}}, plain)
    waypoint = plain["properties"]["waypoint"]["anyOf"][0]["properties"]
    assert waypoint["position_m"]["description"] == "(maxItems 3, minItems 3)"
    check = tool_info("placement_check").parameters.model_dump(exclude_none=True)
    jsonschema.validate(
        {"brick_id": 0, "target_index": 1, "pose": {"position_m": [0, 0, 0]}}, check
    )
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"brick_id": -1, "target_index": 1, "pose": {}}, check)


def test_each_agent_gets_its_tiers_tools() -> None:
    by_agent = agent_tools(ToolTier.CHECK)
    specs = (*agent_specs(ToolTier.CHECK), single_agent_spec(ToolTier.CHECK))
    assert {key: [t.name for t in tools] for key, tools in by_agent.items()} == {
        str(spec.key): list(spec.tools) for spec in specs
    }
    assert not any(agent_tools(ToolTier.NONE).values())
    seeing = agent_tools(ToolTier.CHECK, Observation.IMAGE)
    assert {key: [t.name for t in tools] for key, tools in seeing.items()} == {
        str(spec.key): list(spec.tools) for spec in agent_specs(ToolTier.CHECK, Observation.IMAGE)
    }
    assert all("deproject" in [t.name for t in tools] for tools in seeing.values())


def native_call() -> ChatMessageAssistant:
    calls = [
        ToolCall(id="c1", function="support_contact", arguments={"brick_id": 2}),
        ToolCall(id="c2", function="held_pose", arguments={}, parse_error="not JSON: {brick"),
    ]
    return ChatMessageAssistant(content="Checking first.", tool_calls=calls)


def test_native_tool_calls_reach_the_reasoner_in_band() -> None:
    assert json.loads(in_band(native_call())) == {
        "tool_calls": [
            {"name": "support_contact", "arguments": {"brick_id": 2}},
            {"name": "held_pose", "arguments": "not JSON: {brick"},  # for validation to refuse
        ]
    }
    assert in_band(ChatMessageAssistant(content='{"close": true}')) == '{"close": true}'


def test_tool_results_go_back_as_tool_messages_and_a_refused_call_as_text() -> None:
    own = native_call()
    text = in_band(own)
    results = [{"tool": "support_contact", "result": {"on_ground": True}}, {"error": "bad"}]
    told = f"{TOOL_RESULTS}{json.dumps(results)}\n{NO_MORE_TOOLS}: answer now."
    chat = chat_messages(
        [
            {"role": "user", "content": "prompt"},
            {"role": "assistant", "content": text},
            {"role": "user", "content": told},
            {"role": "assistant", "content": "written by no model"},
        ],
        {text: own},
    )
    assert [type(m) for m in chat] == [
        ChatMessageUser,
        ChatMessageAssistant,
        ChatMessageTool,
        ChatMessageTool,
        ChatMessageUser,
        ChatMessageAssistant,
    ]
    assert chat[1] is own
    assert [(m.tool_call_id, json.loads(m.text)) for m in chat[2:4]] == [  # type: ignore[union-attr]
        ("c1", results[0]),
        ("c2", results[1]),
    ]
    assert chat[4].text == f"{NO_MORE_TOOLS}: answer now." and chat[5].text == "written by no model"
    repair = {"role": "user", "content": "Your answer was refused: ..."}
    refused = chat_messages([{"role": "assistant", "content": text}, repair], {text: own})
    assert [(m.role, m.text) for m in refused] == [("assistant", text), ("user", repair["content"])]


def test_a_prompts_pictures_go_as_inspect_images_after_its_text() -> None:
    picture = Picture("top_down", PictureKind.COLOUR, colour_png(np.zeros((2, 3, 3), np.uint8)))
    prompt = user_message("prompt", [picture, picture])
    (message,) = chat_messages([prompt], {})
    assert isinstance(message, ChatMessageUser) and not isinstance(message.content, str)
    text, *images = message.content
    assert isinstance(text, ContentText) and text.text == "prompt"
    assert [(type(i), getattr(i, "image", None)) for i in images] == [
        (ContentImage, picture.data_url)
    ] * 2


# End to end: inspect eval against actionreasoning eval, over the reference model.


class NativeToolHandler(BaseHTTPRequestHandler):
    """The reference model's chat completions with its tool calls made natively: an answer
    listing ``tool_calls`` goes out as the API's tool calls, and a conversation coming back
    with them and their tool messages is read as the in-band text it stands for. Usage is
    estimated as the reference server does, on that text."""

    server: NativeToolServer

    def do_POST(self) -> None:
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        messages = self.server.in_band(body["messages"])
        content = reply(messages)
        calls = json.loads(content).get("tool_calls")
        message: dict[str, Any] = {"role": "assistant", "content": content}
        if calls:
            ids = [f"call_{self.server.next_id()}" for _ in calls]
            self.server.answers[ids[0]] = content
            message = {
                "role": "assistant",
                "content": None,
                "tool_calls": [
                    {
                        "id": id_,
                        "type": "function",
                        "function": {"name": c["name"], "arguments": json.dumps(c["arguments"])},
                    }
                    for id_, c in zip(ids, calls, strict=True)
                ],
            }
        prompt = sum(estimate_tokens(m["content"]) + TOKENS_PER_MESSAGE for m in messages)
        payload = {
            "id": "native",
            "object": "chat.completion",
            "created": 0,
            "model": body["model"],
            "choices": [{"index": 0, "message": message, "finish_reason": "stop"}],
            "usage": {
                "prompt_tokens": prompt,
                "completion_tokens": estimate_tokens(content),
                "total_tokens": prompt + estimate_tokens(content),
            },
        }
        data = json.dumps(payload).encode()
        self.send_response(200)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def log_message(self, format: str, *args: Any) -> None:
        pass


class NativeToolServer(ThreadingHTTPServer):
    """:class:`NativeToolHandler`'s server on a free loopback port, keeping the in-band
    answer each tool call stands for."""

    def __init__(self) -> None:
        super().__init__(("127.0.0.1", 0), NativeToolHandler)
        self.answers: dict[str, str] = {}  # first call id -> the in-band answer
        self.calls = 0
        self.lock = threading.Lock()

    def next_id(self) -> int:
        with self.lock:
            self.calls += 1
            return self.calls

    def in_band(self, messages: list[dict[str, Any]]) -> list[dict[str, str]]:
        """The conversation as the in-band text the reference model reads."""
        text: list[dict[str, str]] = []
        results: list[Any] = []
        for message in messages:
            if message.get("tool_calls"):
                answer = self.answers[message["tool_calls"][0]["id"]]
                text.append({"role": "assistant", "content": answer})
            elif message["role"] == "tool":
                results.append(json.loads(message["content"]))
            elif results:
                told = json.dumps(results, separators=(",", ":"))
                text.append(
                    {"role": "user", "content": f"{TOOL_RESULTS}{told}\n{message['content']}"}
                )
                results = []
            else:
                text.append({"role": message["role"], "content": message["content"]})
        return text


def serve(server: ThreadingHTTPServer) -> Iterator[str]:
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    host, port = server.server_address[:2]
    yield f"http://{host!s}:{port}/v1"
    server.shutdown()
    server.server_close()


@pytest.fixture(scope="module")
def reference() -> Iterator[str]:
    yield from serve(ReferenceServer(port=0))


@pytest.fixture(scope="module")
def native() -> Iterator[str]:
    yield from serve(NativeToolServer())


@pytest.fixture(scope="module")
def eval_lines(reference: str, tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, Any]]:
    """The pyramid's trials through ``actionreasoning eval`` at seed 0."""
    out = tmp_path_factory.mktemp("eval") / "run"
    result = cli(
        *("eval", "--llm", "openai:reference", "--base-url", reference),
        *("--trials", str(TRIALS), "--seed", "0", "--out", str(out)),
    )
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    return sorted(lines, key=lambda line: line["trial"])


def inspect_eval(url: str, log_dir: Path, *options: str) -> subprocess.CompletedProcess[str]:
    """``inspect eval`` of the task with ``options`` over the OpenAI-compatible server at
    ``url``, logging to ``log_dir``."""
    return inspect(
        *("eval", TASK, "--model", "openai-api/reference/reference", *options),
        *("--log-dir", str(log_dir), "--display", "none"),
        env=server_env(url),
    )


def server_env(url: str) -> dict[str, str]:
    """Where Inspect's OpenAI-compatible provider finds the service ``reference``."""
    return {"REFERENCE_BASE_URL": url, "REFERENCE_API_KEY": "none"}


def the_log(log_dir: Path) -> EvalLog:
    (log,) = log_dir.glob("*.eval")
    return read_eval_log(str(log))


def comparable(line: dict[str, Any]) -> dict[str, Any]:
    """A results line without what two runs of a trial do not share: the code that wrote it
    (a commit may land between them) and the wall-clock latencies."""
    return {k: without_latency(v) for k, v in line.items() if k not in Provenance.model_fields}


def without_latency(data: Any) -> Any:
    if isinstance(data, dict):
        return {k: without_latency(v) for k, v in data.items() if k != "latency_s"}
    if isinstance(data, list):
        return [without_latency(v) for v in data]
    return data


def assert_scored_as_eval(log: EvalLog, lines: list[dict[str, Any]]) -> None:
    """Each sample's results line is eval's but for the model's name (and what
    :func:`comparable` leaves out), and its score is the line's outcome and metrics."""
    assert log.status == "success" and log.samples is not None
    for sample, line in zip(sorted(log.samples, key=lambda s: int(s.id)), lines, strict=True):
        ours = sample.store[RESULT]
        assert ours["llm"] == "inspect:openai-api/reference/reference"
        assert comparable({**ours, "llm": line["llm"]}) == comparable(line)
        score = sample.scores["trial_outcome"]  # type: ignore[index]
        assert score.value == {
            "success": int(line["success"]),
            "bricks_placed": line["bricks_placed"],
            **line["metrics"],
        }
        assert score.answer == (line["failure"] or {}).get("reason", "success")


@pytest.mark.slow
def test_inspect_eval_builds_the_pyramid_as_eval_does(
    reference: str, eval_lines: list[dict[str, Any]], tmp_path: Path
) -> None:
    run = inspect_eval(reference, tmp_path, "-T", f"trials={TRIALS}")
    assert run.returncode == 0, run.stdout + run.stderr
    log = the_log(tmp_path)
    assert_scored_as_eval(log, eval_lines)
    assert all(line["success"] for line in eval_lines)
    assert log.results is not None
    metrics = {name: m.value for name, m in log.results.scores[0].metrics.items()}
    assert metrics["success_rate"] == 1.0 and metrics["ci_high"] == 1.0
    assert 0.3 < metrics["ci_low"] < 0.4  # Wilson's 95 % interval of 2/2: 0.342 .. 1
    for key in ("rotation_error_deg", "center_offset_cm", "iou", "bricks_placed"):
        mean = sum(line["metrics"].get(key, line.get(key)) for line in eval_lines) / TRIALS
        assert metrics[key] == pytest.approx(mean, rel=1e-12)


@pytest.mark.slow
def test_native_tool_calls_take_the_same_turns_as_in_band_ones(
    native: str, eval_lines: list[dict[str, Any]], tmp_path: Path
) -> None:
    run = inspect_eval(native, tmp_path, "-T", "trials=1")
    assert run.returncode == 0, run.stdout + run.stderr
    log = the_log(tmp_path)
    assert_scored_as_eval(log, eval_lines[:1])
    (sample,) = log.samples or []
    models = [event for event in sample.events if event.event == "model"]
    assert any(event.output.message.tool_calls for event in models)
    assert any(isinstance(m, ChatMessageTool) for event in models for m in event.input)


@pytest.mark.slow
def test_a_sample_the_model_api_failed_is_run_again_by_eval_retry(
    reference: str, tmp_path: Path
) -> None:
    """Nothing listens at first: the sample ends with Inspect's error, not a trial failure;
    eval-retry runs the same trial again (one brick, to be quick)."""
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps({**SMALL_PATTERN, "bricks": SMALL_PATTERN["bricks"][:1]}))
    nowhere = f"http://127.0.0.1:{free_port()}/v1"
    options = ("-T", f"pattern={pattern}", "-T", "trials=1", "--max-retries", "0")
    inspect_eval(nowhere, tmp_path / "first", *options)
    log = the_log(tmp_path / "first")
    assert log.status == "error" and log.samples and log.samples[0].error is not None
    (first,) = (tmp_path / "first").glob("*.eval")
    again = inspect(
        "eval-retry", str(first), "--log-dir", str(tmp_path / "again"), env=server_env(reference)
    )
    assert again.returncode == 0, again.stdout + again.stderr
    log = the_log(tmp_path / "again")
    assert log.status == "success" and log.samples
    score = log.samples[0].scores["trial_outcome"]  # type: ignore[index]
    assert score.answer == "success" and score.value["bricks_placed"] == 1  # type: ignore[index]


@pytest.mark.slow
def test_inspect_eval_with_pictures_scores_as_eval_does(reference: str, tmp_path: Path) -> None:
    """``-T observe=image``: the pictures reach the model through Inspect's model API (the
    reference model answers from them alone: the state shows no brick), one brick to be
    quick, scored exactly as ``eval --observe image`` scores the same trial."""
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps({**SMALL_PATTERN, "bricks": SMALL_PATTERN["bricks"][:1]}))
    out = tmp_path / "eval"
    result = cli(
        *("eval", "--llm", "openai:reference", "--base-url", reference, "--pattern", str(pattern)),
        *("--observe", "image", "--trials", "1", "--seed", "0", "--out", str(out)),
    )
    assert result.returncode == 0, result.stderr
    lines = [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]
    assert lines[0]["success"] and lines[0]["llm_usage"]["image_bytes"] > 0
    options = ("-T", f"pattern={pattern}", "-T", "trials=1", "-T", "observe=image")
    run = inspect_eval(reference, tmp_path / "logs", *options)
    assert run.returncode == 0, run.stdout + run.stderr
    log = the_log(tmp_path / "logs")
    assert_scored_as_eval(log, lines)
    (sample,) = log.samples or []
    first = next(event for event in sample.events if event.event == "model").input[0]
    assert isinstance(first.content, list)
    assert [type(part) for part in first.content] == [ContentText] + [ContentImage] * 5
