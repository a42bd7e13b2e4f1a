"""The MCP server `actionreasoning mcp`, driven as a real subprocess by the SDK's own client
over stdio: its tools (every one named in docs/mcp.md), the gates' measurements for the
waiting agent, a one-brick build with the built-in reasoner's answers that gives eval's
line, read_state's state and memory as the prompt's blocks, every result of every tool
within its output schema, a gate's refusal that leaves the arm where it was, answer errors
as eval's, hostile calls refused as typed tool results (a file that does not parse told
without its text), and nothing but protocol messages on stdout."""

from __future__ import annotations

import base64
import dataclasses
import functools
import json
import math
import os
import re
import subprocess
import sys
from collections.abc import Awaitable, Callable, Mapping
from pathlib import Path
from typing import Any

import anyio
import anyio.from_thread
import anyio.to_thread
import pytest
from conftest import SMALL_PATTERN, assert_clean_error, doc_table, eval_lines
from jsonschema.protocols import Validator
from jsonschema.validators import validator_for
from mcp import ClientSession
from mcp.client.stdio import StdioServerParameters, stdio_client

from actionreasoning.agents.answer_errors import CorruptionKind
from actionreasoning.agents.observation import Observation
from actionreasoning.agents.prompt import MEMORY_HEADING, STATE_HEADING, compact_json
from actionreasoning.agents.spec import single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.errors import ToolError
from actionreasoning.reasoners import reference_model
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.llm import TOOL_RESULTS
from actionreasoning.tools.base import ToolModel
from actionreasoning.tools.registry import GATE_MEASUREMENTS, TOOLS, tool_schema
from actionreasoning.trial.rules import Method
from actionreasoning.trial.session import Conditions, TrialSession
from actionreasoning.world.cameras import TOP_DOWN
from actionreasoning.world.pictures import SHOWN_NAMES, read_depth
from actionreasoning.world.scene_spec import FINGERTIPS_BEYOND_TCP_M

COMMAND = [sys.executable, "-m", "actionreasoning", "mcp"]
#: The SDK starts the server in a bare environment: give it the package under test.
ENV = {"PYTHONPATH": os.environ["PYTHONPATH"]} if "PYTHONPATH" in os.environ else None
SERVER = StdioServerParameters(command=COMMAND[0], args=COMMAND[1:], env=ENV)
DOOR_TOOLS = ["start_trial", "read_state", "submit_answer", "finish_trial"]
ONE_BRICK = {**SMALL_PATTERN, "name": "one", "bricks": SMALL_PATTERN["bricks"][:1]}


async def call(client: ClientSession, tool: str, **arguments: Any) -> tuple[dict[str, Any], bool]:
    """Call ``tool``: the result's structured content and whether it is an error."""
    result = await client.call_tool(tool, arguments)
    data = result.structured_content
    assert json.loads(result.content[0].text) == data  # the same JSON as text
    return data, result.is_error


def run(scenario: Callable[[ClientSession], Awaitable[None]], tmp_path: Path) -> None:
    """Run ``scenario`` with a client of a fresh server, whose stderr holds no traceback."""
    log = tmp_path / "server.err"
    with log.open("w") as errlog:

        async def main() -> None:
            async with (
                stdio_client(SERVER, errlog=errlog) as (read, write),
                ClientSession(read, write) as client,
            ):
                init = await client.initialize()
                assert init.instructions and "submit_answer" in init.instructions
                await scenario(client)

        anyio.run(main)
    text = log.read_text()
    assert "Traceback" not in text, text


@pytest.fixture
def one_brick(tmp_path: Path) -> Path:
    path = tmp_path / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


def test_the_tools_are_listed_with_their_schemas(tmp_path: Path) -> None:
    tools: list[Any] = []

    async def scenario(client: ClientSession) -> None:
        tools.extend((await client.list_tools()).tools)

    run(scenario, tmp_path)
    shown = (Observation.STATE, Observation.BOTH)
    specs = [single_agent_spec(t, o) for t in ToolTier for o in shown]
    knowledge = list(dict.fromkeys(n for spec in specs for n in spec.tools))
    registry = list(dict.fromkeys(knowledge + list(GATE_MEASUREMENTS)))
    assert [tool.name for tool in tools] == DOOR_TOOLS + registry
    assert sorted(registry) == sorted(TOOLS)  # every tool, once each
    for tool in tools:
        assert tool.description and tool.input_schema["type"] == "object", tool.name
        if tool.name in registry:
            assert tool.input_schema == tool_schema(tool.name).input_schema
            assert tool.description.startswith(tool_schema(tool.name).description)
    start = next(tool for tool in tools if tool.name == "start_trial")
    assert set(start.input_schema["properties"]) == {
        "pattern", "physics", "noise", "tools", "observe", "seed", "trial", "max_trial_s",
        "answer_errors",
    }  # fmt: skip


def test_the_docs_name_every_tool_the_server_lists(tmp_path: Path) -> None:
    listed: list[str] = []

    async def scenario(client: ClientSession) -> None:
        listed.extend(tool.name for tool in (await client.list_tools()).tools)

    run(scenario, tmp_path)
    rows = doc_table("mcp.md", "Tools (every result is JSON", "| tool | does |")
    named = [name for first, *_ in rows for name in re.findall(r"`(\w+)`", f"`{first}`")]
    assert sorted(named) == sorted(listed)  # each once


@pytest.mark.slow  # two whole trials
def test_the_builtin_reasoners_answers_build_a_brick_and_give_evals_line(
    tmp_path: Path, one_brick: Path
) -> None:
    """Each answer is the built-in reasoner's, computed in this process on a twin of the
    trial (the same spec) whose tool calls go to the server; the twin is answered alike."""
    # The solve tier, whose tools the built-in reasoner calls by name here.
    line = json.loads(eval_lines(tmp_path / "eval", one_brick, Method.AGENTS, tools="solve"))
    twin = TrialSession(Conditions.load(str(one_brick), tools="solve").spec(seed=3, trial=0))
    agents: list[str] = []
    tool_calls: list[str] = []

    async def scenario(client: ClientSession) -> None:
        data, refused = await call(
            client, "start_trial", pattern=str(one_brick), seed=3, tools="solve"
        )
        assert not refused and data["previous_result"] is None
        assert data["trial"] == {
            "pattern": str(one_brick), "physics": "paper", "noise": "none", "tools": "solve",
            "seed": 3, "trial": 0,
        }  # fmt: skip

        def call_tool(name: str, arguments: Mapping[str, Any]) -> ToolModel:
            tool_calls.append(name)
            data, refused = anyio.from_thread.run(
                functools.partial(call, client, name, **arguments)
            )
            if refused:
                raise ToolError(data["refusal"]["detail"])
            return TOOLS[name].output_model.model_validate(data["result"])

        while True:
            state, _ = await call(client, "read_state")
            if state["result"] is not None:
                break
            request = twin.request
            turn = state["turn"]
            assert (turn["agent"], turn["prompt"]) == (str(request.spec.key), request.prompt)
            assert [tool["name"] for tool in turn["tools"]] == list(request.spec.tools)
            asked = dataclasses.replace(request, call_tool=call_tool)
            reply = await anyio.to_thread.run_sync(BuiltinReasoner().decide, asked)
            answer = reply.answer.model_dump(mode="json")
            judged, refused = await call(client, "submit_answer", answer=answer)
            assert not refused and judged["call"]["outcome"] == "accepted", judged
            twin.answer(json.dumps(answer))
            agents.append(judged["call"]["agent"])
        finished, refused = await call(client, "finish_trial")
        assert not refused and finished["result"] == state["result"]
        again, refused = await call(client, "read_state")
        assert refused and again["refusal"]["code"] == "no_trial"
        lines.append(finished["result"])

    lines: list[dict[str, Any]] = []
    try:
        run(scenario, tmp_path)
    finally:
        twin.close()
    assert agents == ["pre_grasp", "descent", "grasp", "lift", "placement", "placement", "release"]
    # Ag5's set-down asks for the slot, then for it with the brick's further roll.
    assert tool_calls == ["grasp_options", "placement_pose", "placement_pose", "placement_pose"]
    result = lines[0]
    assert result["success"] and result["bricks_placed"] == 1 and result["llm"] == "mcp"
    assert {**result, "llm": "builtin"} == line  # the whole line, but who answered


def blocks(prompt: str) -> tuple[Any, Any]:
    """The state and memory blocks of an agent's prompt, parsed."""
    parsed = []
    for heading in (STATE_HEADING, MEMORY_HEADING):
        block = re.search(re.escape(heading) + r"\n```json\n(.*?)\n```", prompt, flags=re.S)
        assert block is not None, heading
        parsed.append(json.loads(block.group(1)))
    state, memory = parsed
    return state, memory


def test_read_state_shows_the_state_and_memory_blocks_of_its_prompt(tmp_path: Path) -> None:
    """At the first agent and after each accepted answer (the prompt-only reference
    model's, in the tier without tools), up to Ag5's second call."""
    turns: list[dict[str, Any]] = []

    async def scenario(client: ClientSession) -> None:
        start, _ = await call(client, "start_trial", pattern="pyramid", seed=0, tools="none")
        read, _ = await call(client, "read_state")
        assert read["turn"] == start["turn"]
        turns.append(read["turn"])
        for _ in range(5):
            text = reference_model.reply([{"role": "user", "content": turns[-1]["prompt"]}])
            judged, refused = await call(client, "submit_answer", answer=text)
            assert not refused and judged["call"]["outcome"] == "accepted", judged
            read, _ = await call(client, "read_state")
            turns.append(read["turn"])

    run(scenario, tmp_path)
    assert [turn["agent"] for turn in turns] == [
        "pre_grasp", "descent", "grasp", "lift", "placement", "placement",
    ]  # fmt: skip
    for turn in turns:
        assert (turn["state"], turn["memory"]) == blocks(turn["prompt"]), turn["agent"]
    first, carry = turns[0], turns[4]
    assert set(first["state"]) == {"robot", "bricks", "targets"} and first["memory"] == {}
    assert "tool_pose" in first["state"]["robot"]
    assert (carry["memory"]["current_brick"], carry["memory"]["phase"]) == (0, "carry")
    decided = [step["agent"] for step in carry["memory"]["this_brick"]]
    assert decided == ["pre_grasp", "descent", "grasp", "lift"]


Checked = Callable[..., Awaitable[tuple[dict[str, Any], bool]]]


async def run_every_tool(checked: Checked, turn: dict[str, Any]) -> None:
    """Run each of the waiting agent's tools and each gate measurement, on its current
    brick and target (brick 0 and target 0 before one is chosen), the tool's pose and the
    top-down depth picture's centre."""
    memory = turn["memory"]
    values = {
        "brick_id": memory.get("current_brick", 0),
        "target_index": memory.get("current_target", 0),
        "pose": turn["state"]["robot"]["tool_pose"],
        "camera": "top_down",
        "u": 320,
        "v": 320,
    }
    for tool in turn["tools"] + turn["measurements"]:
        await checked(
            tool["name"], **{name: values[name] for name in tool["input_schema"]["required"]}
        )


async def answer_by_reference(checked: Checked, prompt: str) -> None:
    """Answer the waiting agent as the prompt-only reference model does: its tool calls
    submitted and their results told back, until it decides; the decision accepted."""
    messages = [{"role": "user", "content": prompt}]
    while True:
        text = reference_model.reply(messages)
        judged, refused = await checked("submit_answer", answer=text)
        assert not refused, judged
        if judged["call"] is not None:
            assert judged["call"]["outcome"] == "accepted", judged
            return
        results = [{"tool": tool["tool"], "result": tool["result"]} for tool in judged["tools"]]
        told = f"{TOOL_RESULTS}{compact_json(results)}\nCall more tools, or answer."
        messages += [{"role": "assistant", "content": text}, {"role": "user", "content": told}]


async def lift_without_duration(checked: Checked, turn: dict[str, Any]) -> None:
    """Lift with no duration, as fast as the arm goes: the gate refuses the speed, which
    is not finite and so written as null."""
    tool = turn["state"]["robot"]["tool_pose"]
    x, y, z = tool["position_m"]
    waypoint = {"position_m": [x, y, z + 0.1], "quat_xyzw": tool["quat_xyzw"], "path": "linear"}
    judged, refused = await checked(
        "submit_answer", answer={"rationale": "up", "waypoint": waypoint}
    )
    assert not refused and judged["call"]["outcome"] == "refused", judged
    checks = {c["name"]: c["value"] for gate in judged["call"]["gates"] for c in gate["checks"]}
    assert checks["speed_mps"] is None


@pytest.mark.slow  # two whole trials
def test_every_result_of_every_tool_is_of_its_output_schema(
    tmp_path: Path, one_brick: Path
) -> None:
    """Each tool refused before a trial starts; then, in the two tiers with tools (whose
    agents hold every tool; the check tier with pictures, whose agents also deproject), a
    one-brick trial: the first agent's tools and the gates'
    measurements refused once each, every tool of every waiting agent and every gate
    measurement run, a lift refused for a speed that is not finite, and the reference
    model's answers. Each result is checked by jsonschema and by the SDK's client against
    the tool's output schema."""
    validators: dict[str, Validator] = {}
    seen: set[tuple[str, bool]] = set()

    async def scenario(client: ClientSession) -> None:
        for tool in (await client.list_tools()).tools:
            schema = tool.output_schema
            assert schema is not None and schema["type"] == "object", tool.name
            check = validator_for(schema)
            check.check_schema(schema)
            validators[tool.name] = check(schema)
            assert not validators[tool.name].is_valid({}), tool.name  # neither reply nor refusal

        async def checked(tool: str, **arguments: Any) -> tuple[dict[str, Any], bool]:
            # The SDK's client checks a result without isError against the tool's schema;
            # a refused one, only when asked.
            result = await client.call_tool(tool, arguments)
            await client.validate_tool_result(tool, result)
            data = result.structured_content
            assert data is not None
            validators[tool].validate(data)
            seen.add((tool, result.is_error))
            return data, result.is_error

        for name in validators:
            arguments = {"seed": -1} if name == "start_trial" else {}
            data, refused = await checked(name, **arguments)
            assert refused and "refusal" in data, (name, data)
        for tier, observe in (("solve", "state"), ("check", "both")):
            data, _ = await checked(
                "start_trial", pattern=str(one_brick), seed=0, tools=tier, observe=observe
            )
            tools = [tool["name"] for tool in data["turn"]["tools"]]
            for name in [*tools, *GATE_MEASUREMENTS]:
                refused_call, refused = await checked(name)  # no arguments
                assert refused and refused_call["refusal"]["code"] == "tool_error", name
            _, refused = await checked("submit_answer", answer="{")
            assert refused
            fast_lift = True
            while (turn := data["turn"]) is not None:
                await run_every_tool(checked, turn)
                if turn["agent"] == "lift" and fast_lift:
                    fast_lift = False
                    await lift_without_duration(checked, turn)
                else:
                    await answer_by_reference(checked, turn["prompt"])
                data, _ = await checked("read_state")
            assert data["result"]["success"], data["result"]
            finished, refused = await checked("finish_trial")
            assert not refused and finished["result"] == data["result"]

    run(scenario, tmp_path)
    assert seen == {(name, refused) for name in validators for refused in (False, True)}


def shown_brick(state: dict[str, Any], brick: int) -> dict[str, Any]:
    """Brick ``brick`` of a turn's state."""
    return next(shown for shown in state["bricks"] if shown["id"] == brick)


def answer_at(state: dict[str, Any], brick: int, **fields: Any) -> dict[str, Any]:
    """A pre-grasp answer for brick 0 and target 0 with its waypoint at brick ``brick``'s
    centre, and ``fields``."""
    centre = shown_brick(state, brick)["pose"]["position_m"]
    waypoint = {"position_m": centre, "quat_xyzw": [1, 0, 0, 0]}
    return {"brick_id": 0, "target_index": 0, "waypoint": waypoint} | fields


def test_the_gates_measurements_answer_any_waiting_agent_and_are_logged_with_its_call(
    tmp_path: Path,
) -> None:
    async def scenario(client: ClientSession) -> None:
        start, _ = await call(client, "start_trial", pattern="pyramid", seed=0)
        turn = start["turn"]
        assert [tool["name"] for tool in turn["measurements"]] == list(GATE_MEASUREMENTS)
        state = turn["state"]
        pose = state["robot"]["tool_pose"]
        results = {}
        for name, arguments in (
            ("reachability", {"pose": pose}),
            ("slip_estimate", {"brick_id": 0}),
            ("alignment_errors", {"brick_id": 0, "target_index": 0}),
        ):
            data, refused = await call(client, name, **arguments)
            assert not refused and data["tool"] == name, data
            results[name] = TOOLS[name].output_model.model_validate(data["result"])
        assert results["reachability"].reachable  # where the arm is
        target = state["targets"][0]["pose"]["position_m"]
        planar = math.dist(shown_brick(state, 0)["pose"]["position_m"][:2], target[:2])
        # The state as the prompt shows it: positions to 0.01 mm.
        assert results["alignment_errors"].e_xy_norm_m == pytest.approx(planar, abs=2e-5)
        # The answer's record holds every tool the outside agent ran for it.
        judged, _ = await call(client, "submit_answer", answer=answer_at(state, brick=1))
        assert [tool["name"] for tool in judged["call"]["tool_calls"]] == list(results)
        assert judged["call"]["tool_calls"][0]["result"] == results["reachability"].model_dump(
            mode="json"
        )

    run(scenario, tmp_path)


def test_an_answer_a_gate_refuses_comes_back_with_its_feedback_and_the_arm_stays(
    tmp_path: Path,
) -> None:
    async def scenario(client: ClientSession) -> None:
        before, _ = await call(client, "start_trial", pattern="pyramid", seed=0)
        state = before["turn"]["state"]
        # Approach brick 0 through the middle of brick 1: valid data, and refused before it
        # moves, the approach being no hover over the brick chosen.
        judged, refused = await call(client, "submit_answer", answer=answer_at(state, brick=1))
        call_record = judged["call"]
        assert not refused and judged["agent"] == "pre_grasp" and judged["result"] is None
        assert call_record["outcome"] == "refused"
        choice, plan = call_record["gates"]
        assert (choice["gate"], choice["passed"]) == ("pre_grasp_choice", True)
        assert plan["gate"] == "pre_grasp_plan" and not plan["passed"]
        failed = {c["name"]: c["value"] for c in plan["checks"] if not c["passed"]}
        # The fingertips in the ground beside brick 0, under its top: no hover over it.
        chosen, through = shown_brick(state, 0), shown_brick(state, 1)
        top = chosen["pose"]["position_m"][2] + chosen["size_m"][2] / 2
        hover = through["pose"]["position_m"][2] - FINGERTIPS_BEYOND_TCP_M - top
        assert failed["hover_clearance_m"] == pytest.approx(hover, abs=2e-5)  # shown to 0.01 mm
        assert call_record["feedback"].startswith("pre_grasp_plan failed: hover_clearance_m = ")
        after, _ = await call(client, "read_state")
        assert after["turn"]["feedback"] == call_record["feedback"]
        assert after["turn"]["state"] == state  # nothing moved: the same measured state

    run(scenario, tmp_path)


def test_answer_errors_corrupt_the_agents_answers_and_the_line_counts_them_as_evals(
    tmp_path: Path,
) -> None:
    async def scenario(client: ClientSession) -> None:
        for rate, detail in (
            (-0.5, "greater than or equal to 0"),
            (1.5, "less than or equal to 1"),
            (math.nan, "a valid number"),  # sent as null
            (True, "a valid number"),
            ("0.5", "a valid number"),
        ):
            data, refused = await call(client, "start_trial", answer_errors=rate)
            assert refused and data["refusal"]["code"] == "invalid_action", (rate, data)
            assert (
                data["refusal"]["detail"] == f"start_trial: answer_errors: Input should be {detail}"
            )
        clean, refused = await call(client, "start_trial", answer_errors=-0.0)  # -0 is 0: none
        assert not refused and "answer_errors" not in clean["trial"]
        start, refused = await call(client, "start_trial", seed=0, answer_errors=1.0)
        assert not refused and start["trial"]["answer_errors"] == 1.0
        assert "answer_errors" not in start["previous_result"]  # eval's line at rate 0
        judged, refused = await call(
            client, "submit_answer", answer=answer_at(start["turn"]["state"], brick=0)
        )
        corruption = judged["call"]["corruption"]  # every answer at rate 1
        assert not refused and corruption["kind"] in set(CorruptionKind), judged
        assert judged["call"]["outcome"] == "refused"  # and the gates caught it
        finished, _ = await call(client, "finish_trial")
        counts = finished["result"]["answer_errors"]
        assert counts["corrupted"] == 1 and counts["by_kind"] == {corruption["kind"]: 1}
        assert counts["caught"] == {corruption["kind"]: {"before": 1}}

    run(scenario, tmp_path)


SECRET = "sk-live-5f3a9c2e7b1d40681f2a"


def test_a_file_that_does_not_parse_is_told_by_line_and_column_never_by_its_text(
    tmp_path: Path,
) -> None:
    files = {
        "pattern": ("open.yaml", f'name: x\nbricks: []\napi_key: "{SECRET}\nbrick_size: full\n'),
        "physics": ("tab.yaml", f"name: p\n\ttoken: {SECRET}\n"),
        "noise": ("alias.yml", f"name: n\npassword: *{SECRET}\n"),
    }
    told = {
        "pattern": "(while scanning a quoted scalar at line 3, column 10; found unexpected end "
        "of stream at line 5, column 1)",
        "physics": "(while scanning for the next token; found character '\\t' that cannot "
        "start any token at line 2, column 1)",
        "noise": "(found undefined alias '...' at line 2, column 11)",
    }
    for name, text in files.values():
        (tmp_path / name).write_text(text)

    async def scenario(client: ClientSession) -> None:
        for argument, (name, _) in files.items():
            path = tmp_path / name
            data, refused = await call(client, "start_trial", **{argument: str(path)})
            assert refused and data["refusal"]["code"] == "invalid_action", data
            detail = data["refusal"]["detail"]
            assert detail == f"start_trial: {path}: not valid YAML {told[argument]}", detail
            assert SECRET[3:] not in json.dumps(data)

    run(scenario, tmp_path)


NAN_WAYPOINT = '{"brick_id": 0, "target_index": 0, "waypoint": {"position_m": [NaN, 0, 0.2]}}'


def test_hostile_calls_get_typed_refusals_and_nothing_moves(tmp_path: Path) -> None:
    from test_gates import TIGHT

    tight = tmp_path / "tight.json"
    tight.write_text(json.dumps(TIGHT))

    async def scenario(client: ClientSession) -> None:
        for tool in ("read_state", "submit_answer", "grasp_options", "finish_trial"):
            arguments = {"answer": {}} if tool == "submit_answer" else {}
            data, refused = await call(client, tool, **arguments)
            assert refused and data["refusal"]["code"] == "no_trial", tool
        for arguments, detail in (
            ({"seed": -1}, "seed: Input should be greater than or equal to 0"),
            ({"seed": "3"}, "seed: Input should be a valid integer"),
            ({"seed": 1.5}, "seed: Input should be a valid integer"),
            ({"pattern": "nowhere.json"}, "nowhere.json"),
            ({"physics": "moon"}, "moon"),
            ({"max_trial_s": math.inf}, "max_trial_s"),
            ({"trials": 2}, "trials: Extra inputs are not permitted"),
            ({"tools": "all"}, "not a tier (tiers: solve, check, none)"),
            ({"pattern": "p" * 100_000}, "pattern: file name too long (100000 characters)"),
            ({"pattern": "a\0b.json"}, "pattern: contains a NUL byte"),
            ({"physics": "a\0b.json"}, "physics: contains a NUL byte"),
            ({"noise": "n" * 300 + ".yaml"}, "noise: file name too long"),
            ({"pattern": str(tight)}, "the joint between targets 0 and 1 is 0.0 mm"),
        ):
            data, refused = await call(client, "start_trial", **arguments)
            assert refused and data["refusal"]["code"] == "invalid_action", arguments
            assert detail in data["refusal"]["detail"], data
        start, _ = await call(client, "start_trial", pattern="pyramid", seed=0, tools="solve")
        state = start["turn"]["state"]
        far = {"position_m": [2.5, -0.1, 0.2], "quat_xyzw": [1, 0, 0, 0]}
        for tool, arguments, code, detail in (
            ("rm -rf /", {}, "unknown_tool", "no tool 'rm -rf /'"),
            ("slip_estimate", {"brick_id": 99}, "tool_error", "no brick with id 99"),
            ("slip_estimate", {"brick_id": -1}, "tool_error", "brick_id"),
            ("slip_estimate", {"brick_id": 0, "force": 1}, "tool_error", "Extra inputs"),
            ("alignment_errors", {"brick_id": 0}, "tool_error", "target_index: Field required"),
            ("alignment_errors", {"brick_id": 0, "target_index": 99}, "tool_error", "no target 99"),
            ("reachability", {"pose": far | {"position_m": [1e300, 0, 0]}}, "tool_error", "100 m"),
            ("reachability", {"pose": far | {"quat_xyzw": [0, 0, 0, 0]}}, "tool_error", "unit"),
            (
                "reachability",
                {"pose": far | {"position_m": [math.nan, 0, 0]}},
                "tool_error",
                "pose",
            ),
            ("reachability", {"pose": "here"}, "tool_error", "pose"),
            ("collision_check", {"pose": far}, "unknown_tool", "of pre_grasp"),
            ("grasp_options", {"brick_id": 99, "target_index": 0}, "tool_error", "99"),
            (
                "grasp_options",
                {"brick_id": 0, "target_index": 0, "descent_opening_m": math.nan},
                "tool_error",
                "descent_opening_m",
            ),
            ("submit_answer", {"answer": '{"brick_id": 0,'}, "invalid_answer", "not valid JSON"),
            (
                "submit_answer",
                {"answer": '{"brick_id": ' + "9" * 5000 + "}"},
                "invalid_answer",
                "more than 4300 digits",
            ),
            ("submit_answer", {"answer": NAN_WAYPOINT}, "invalid_answer", "finite number"),
            ("submit_answer", {"answer": 42}, "invalid_action", "answer"),
            ("submit_answer", {}, "invalid_action", "answer: Field required"),
            (
                "submit_answer",
                {"answer": answer_at(state, brick=0) | {"waypoint": far}},
                "invalid_answer",
                "outside the workspace box",
            ),
            (
                "submit_answer",
                {"answer": {"tool_calls": [{"name": "reachability", "arguments": {}}]}},
                "invalid_answer",
                "not one of your tools",
            ),
        ):
            data, refused = await call(client, tool, **arguments)
            assert refused and data["refusal"]["code"] == code, (tool, arguments, data)
            assert detail in data["refusal"]["detail"], data
        now, _ = await call(client, "read_state")
        assert now["turn"]["agent"] == "pre_grasp" and now["turn"]["state"] == state
        assert now["result"] is None
        # A second start abandons the first trial and says so.
        again, refused = await call(client, "start_trial", pattern="pyramid", seed=0, trial=1)
        previous = again["previous_result"]
        assert not refused and previous["failure"]["reason"] == "abandoned"
        assert previous["llm"] == "mcp" and (previous["seed"], previous["trial"]) == (0, 0)
        assert again["trial"]["trial"] == 1 and again["turn"]["agent"] == "pre_grasp"
        finished, _ = await call(client, "finish_trial")
        assert finished["result"]["failure"]["reason"] == "abandoned"

    run(scenario, tmp_path)


def test_stdout_holds_only_protocol_messages_whatever_comes_in() -> None:
    """Raw stdio, line by line: a line that is not JSON, a NaN in a tool's arguments and
    arguments that are no object get answers (a parse error with id null for the first)
    and the server goes on; a
    trial runs and prints nothing on the wire; stdin's end stops the server cleanly."""
    initialize = {
        "protocolVersion": "2025-06-18",
        "capabilities": {},
        "clientInfo": {"name": "raw", "version": "0"},
    }

    def request(id_: int, method: str, **params: Any) -> str:
        return json.dumps({"jsonrpc": "2.0", "id": id_, "method": method, "params": params})

    def tool(id_: int, name: str, arguments: Any) -> str:
        return request(id_, "tools/call", name=name, arguments=arguments)

    nan_args = '{"brick_id": 0, "target_index": 0, "descent_opening_m": NaN}'
    sent = [
        (request(1, "initialize", **initialize), None),
        ('{"jsonrpc": "2.0", "method": "notifications/initialized"}', None),
        ("this is not JSON {", None),
        (tool(2, "start_trial", {"seed": 0, "tools": "solve"}), "result"),
        (tool(3, "grasp_options", {}).replace("{}", nan_args), "result"),
        (tool(4, "grasp_options", [1]), "error"),
        (tool(5, "finish_trial", {}), "result"),
    ]
    server = subprocess.Popen(
        COMMAND,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    received: list[dict[str, Any]] = []
    try:
        assert server.stdin is not None and server.stdout is not None
        for line, _ in sent:
            server.stdin.write(line + "\n")
            server.stdin.flush()
            wanted = json.loads(line).get("id") if line.startswith("{") else None
            while wanted is not None:
                message = json.loads(server.stdout.readline())  # each line is JSON-RPC
                assert message["jsonrpc"] == "2.0", message
                received.append(message)
                if message.get("id") == wanted:
                    break
        server.stdin.close()
        assert server.wait(timeout=60) == 0
        assert server.stdout.read() == ""
    finally:
        if server.poll() is None:
            server.kill()
    by_id = {message.get("id"): message for message in received}
    for line, outcome in sent:
        if outcome is not None:
            assert outcome in by_id[json.loads(line)["id"]], by_id
    assert by_id[None]["error"]["code"] == -32700  # the line that is not JSON
    nan = by_id[3]["result"]
    assert nan["isError"] and nan["structuredContent"]["refusal"]["code"] == "tool_error"
    assert by_id[5]["result"]["structuredContent"]["result"]["failure"]["reason"] == "abandoned"
    assert server.stderr is not None and "Traceback" not in server.stderr.read()


def test_without_the_sdk_the_command_says_which_extra_in_one_line() -> None:
    without = "import sys; sys.modules['mcp'] = None\nfrom actionreasoning.cli import app\n"
    code = without + "app(['mcp'], prog_name='actionreasoning')"
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert_clean_error(done, "MCP SDK", "actionreasoning[mcp]")


def test_with_pictures_the_turn_comes_with_them_as_png_image_content(
    tmp_path: Path, one_brick: Path
) -> None:
    """observe "both": start_trial and read_state return the waiting agent's pictures after
    their JSON, as the turn names them; the depth picture decodes to the camera's size and
    the prompt-only reference model answers the prompt that comes with them."""
    names = list(SHOWN_NAMES)

    async def scenario(client: ClientSession) -> None:
        start = await client.call_tool(
            "start_trial",
            {"pattern": str(one_brick), "seed": 3, "observe": "both", "tools": "none"},
        )
        data = start.structured_content
        assert not start.is_error and data["trial"]["observe"] == "both"
        assert data["turn"]["pictures"] == names and "## Cameras" in data["turn"]["prompt"]
        images = start.content[1:]
        assert [image.mime_type for image in images] == ["image/png"] * len(names)
        depth = read_depth(base64.b64decode(images[names.index("top_down.depth")].data))
        assert depth.shape == (TOP_DOWN.height, TOP_DOWN.width)
        text = reference_model.reply([{"role": "user", "content": data["turn"]["prompt"]}])
        judged, refused = await call(client, "submit_answer", answer=text)
        assert not refused and judged["call"]["outcome"] == "accepted", judged
        read = await client.call_tool("read_state", {})
        assert read.structured_content["turn"]["agent"] == "descent"
        assert len(read.content) == 1 + len(names)
        assert [image.data for image in read.content[1:]] != [image.data for image in images]

    run(scenario, tmp_path)
