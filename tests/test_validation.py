"""A model's answer is data: parsed, validated and bounded before anything can use it."""

from __future__ import annotations

import itertools
import json
import math

import pytest
from conftest import built_state

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.outputs import (
    AgentAnswer,
    DescentAnswer,
    DescentDecision,
    GraspAnswer,
    LiftDecision,
    PlacementAnswer,
    PlacementDecision,
    PreGraspAnswer,
    PreGraspDecision,
    RegraspRequest,
    ReleaseDecision,
    SingleAgentAnswer,
)
from actionreasoning.agents.spec import agent_specs, single_agent_spec
from actionreasoning.agents.validation import OutputError, parse_answer
from actionreasoning.world.geometry import top_down_quat

STATE = built_state("pyramid")
AGENTS = {spec.key: spec for spec in (*agent_specs(), single_agent_spec())}
DOWN = list(top_down_quat(0.0))


def waypoint(position=(0.5, 0.1, 0.2), quat=DOWN) -> dict:
    return {"position_m": list(position), "quat_xyzw": list(quat)}


def test_a_valid_answer_parses_even_inside_a_code_fence() -> None:
    text = "```json\n" + json.dumps({"brick_id": 2, "target_index": 0, "waypoint": waypoint()})
    answer = parse_answer(text + "\n```", AGENTS["pre_grasp"], STATE)
    assert isinstance(answer, PreGraspAnswer)
    assert answer.brick_id == 2


def test_a_nearly_unit_quaternion_is_normalised() -> None:
    quat = [q * 1.0004 for q in DOWN]
    answer = parse_answer(json.dumps({"waypoint": waypoint(quat=quat)}), AGENTS["lift"], STATE)
    assert math.isclose(sum(q * q for q in answer.waypoint.quat_xyzw), 1.0, abs_tol=1e-12)


@pytest.mark.parametrize(
    ("agent", "text", "needle"),
    [
        ("lift", "close the gripper please", "not valid JSON"),
        ("lift", "[1, 2, 3]", "JSON object, not list"),
        ("lift", '{"waypoint": ', "not valid JSON"),
        ("lift", "[" * 100_000 + "]" * 100_000, "characters"),
        ("lift", "[" * 5000 + "]" * 5000, "nested too deeply"),
        # Python refuses to convert an integer of more than 4300 digits (a ValueError).
        ("pre_grasp", '{"brick_id": ' + "9" * 5000 + "}", "more than 4300 digits"),
        ("lift", json.dumps({"waypoint": waypoint(), "run": "rm -rf /"}), "run: Extra inputs"),
        (
            "lift",
            '{"waypoint": {"position_m": [NaN, 0, 0.2], "quat_xyzw": [1, 0, 0, 0]}}',
            "finite",
        ),
        (
            "lift",
            json.dumps({"waypoint": waypoint(position=(1e9, 0, 0.2))}),
            "outside the workspace",
        ),
        ("lift", json.dumps({"waypoint": waypoint(position=(0.5, 0.1, -0.1))}), "outside"),
        ("lift", json.dumps({"waypoint": waypoint(quat=(0, 0, 0, 0))}), "quaternion norm 0.0000"),
        ("lift", json.dumps({"waypoint": waypoint(quat=(1, 1, 0, 0))}), "quaternion norm 1.4142"),
        ("lift", json.dumps({"waypoint": {"position_m": "up", "quat_xyzw": DOWN}}), "position_m"),
        ("pre_grasp", json.dumps({"brick_id": 17, "waypoint": waypoint()}), "brick_id 17"),
        ("pre_grasp", json.dumps({"target_index": 6}), "target_index 6 names no target"),
        ("pre_grasp", json.dumps({"brick_id": -1}), "brick_id: Input should be greater"),
        (
            "lift",
            json.dumps({"tool_calls": [{"name": "__import__('os').system('ls')"}]}),
            "is not one of your tools",
        ),
        ("lift", json.dumps({"tool_calls": [{"name": "alignment_errors"}]}), "not one of your"),
        (
            "placement",
            json.dumps({"tool_calls": [{"name": "held_pose", "arguments": {"brick_id": "x"}}]}),
            "tool_calls[0] (held_pose): brick_id",
        ),
        ("lift", json.dumps({"rationale": "x" * 5000}), "rationale: String should have at most"),
        ("descent", json.dumps({"gripper_opening_m": 5.0}), "gripper_opening_m: Input should be"),
        (
            "lift",
            json.dumps({"waypoint": {**waypoint(), "duration_s": 0}}),
            "duration_s: Input should be greater than 0",
        ),
        (
            "lift",
            json.dumps({"waypoint": {**waypoint(), "duration_s": 1e6}}),
            "duration_s: Input should be less than or equal to 30",
        ),
    ],
)
def test_hostile_answers_are_refused_with_a_short_reason(
    agent: str, text: str, needle: str
) -> None:
    with pytest.raises(OutputError) as refused:
        parse_answer(text, AGENTS[agent], STATE)
    message = str(refused.value)
    assert needle in message
    assert len(message) < 400


def test_a_chosen_duration_and_a_regrasp_survive_validation() -> None:
    slow = {**waypoint(), "duration_s": 12.5}
    lift = parse_answer(json.dumps({"waypoint": slow}), AGENTS["lift"], STATE)
    regrasp = parse_answer(json.dumps({"regrasp": True}), AGENTS["placement"], STATE)
    assert lift.waypoint.duration_s == 12.5
    assert isinstance(regrasp, PlacementAnswer) and regrasp.regrasp and regrasp.waypoint is None


def test_answers_keep_their_schema() -> None:
    placement = parse_answer(json.dumps({"waypoint": waypoint()}), AGENTS["placement"], STATE)
    opened = {"gripper_opening_m": 0.13, "waypoint": waypoint()}
    descent = parse_answer(json.dumps(opened), AGENTS["descent"], STATE)
    assert isinstance(placement, PlacementAnswer) and isinstance(descent, DescentAnswer)


# --- a tool turn, or a complete decision ------------------------------------------------
#: Each agent's complete decision (its decision fields in the order the refusal names them)
#: and the typed decision it parses into.
COMPLETE: dict[str, tuple[dict, type[AgentAnswer]]] = {
    "pre_grasp": (
        {"brick_id": 2, "target_index": 0, "waypoint": waypoint()},
        PreGraspDecision,
    ),
    "descent": ({"gripper_opening_m": 0.13, "waypoint": waypoint()}, DescentDecision),
    "lift": ({"waypoint": waypoint()}, LiftDecision),
    "placement": ({"waypoint": waypoint()}, PlacementDecision),
    "release": ({"gripper_opening_m": 0.13, "waypoint": waypoint()}, ReleaseDecision),
}
#: Every way to leave fields of a complete decision out, or null.
INCOMPLETE = [
    (agent, left_out, null)
    for agent, (answer, _) in COMPLETE.items()
    for size in range(1, len(answer) + 1)
    for left_out in itertools.combinations(answer, size)
    for null in (False, True)
]


def needs(agent: str, left_out: tuple[str, ...]) -> str:
    """The refusal of ``agent``'s answer without ``left_out``: the words of the orchestrator's
    hand check before the schema refused it."""
    fields = list(COMPLETE[agent][0])
    return f"the answer needs {', '.join(fields)}; missing: {', '.join(left_out)}"


def without(answer: dict, left_out: tuple[str, ...], null: bool) -> dict:
    kept = {name: value for name, value in answer.items() if name not in left_out}
    return kept | dict.fromkeys(left_out) if null else kept


@pytest.mark.parametrize(("agent", "left_out", "null"), INCOMPLETE)
def test_an_incomplete_decision_is_refused_by_the_schema_naming_what_is_missing(
    agent: str, left_out: tuple[str, ...], null: bool
) -> None:
    answer = without(COMPLETE[agent][0], left_out, null)
    with pytest.raises(OutputError) as refused:
        parse_answer(json.dumps(answer), AGENTS[agent], STATE)
    assert str(refused.value) == needs(agent, left_out)
    assert refused.value.category is ErrorCategory.SCHEMA


@pytest.mark.parametrize(("stage", "left_out", "null"), INCOMPLETE)
def test_the_single_agents_incomplete_step_is_refused_as_its_stages_agent_would_be(
    stage: str, left_out: tuple[str, ...], null: bool
) -> None:
    answer = {"step": stage} | without(COMPLETE[stage][0], left_out, null)
    with pytest.raises(OutputError) as refused:
        parse_answer(json.dumps(answer), AGENTS["single_agent"], STATE)
    assert str(refused.value) == needs(stage, left_out)
    assert refused.value.category is ErrorCategory.SCHEMA


def test_the_single_agents_answer_without_a_step_is_refused() -> None:
    with pytest.raises(OutputError) as refused:
        parse_answer(json.dumps({"waypoint": waypoint()}), AGENTS["single_agent"], STATE)
    assert str(refused.value) == "the answer needs step; missing: step"
    assert refused.value.category is ErrorCategory.SCHEMA


@pytest.mark.parametrize(
    ("agent", "answer", "decision"),
    [
        *((agent, answer, decision) for agent, (answer, decision) in COMPLETE.items()),
        ("grasp", {"close": True}, GraspAnswer),
        ("grasp", {"close": True, "waypoint": waypoint()}, GraspAnswer),
        ("placement", {"regrasp": True}, RegraspRequest),
        (
            "single_agent",
            {"step": "pre_grasp", "brick_id": 2, "target_index": 0, "waypoint": waypoint()},
            SingleAgentAnswer,
        ),
        ("single_agent", {"step": "lift", "waypoint": waypoint()}, SingleAgentAnswer),
        ("single_agent", {"step": "grasp", "close": True}, SingleAgentAnswer),
    ],
)
def test_a_complete_decision_parses_into_its_typed_decision(
    agent: str, answer: dict, decision: type[AgentAnswer]
) -> None:
    parsed = parse_answer(json.dumps(answer), AGENTS[agent], STATE)
    assert type(parsed) is decision
    assert set(parsed.model_dump(exclude_defaults=True)) == set(answer)


#: A valid call of one of each agent's tools.
TOOL_CALLS = {
    "pre_grasp": {"name": "reachability", "arguments": {"pose": waypoint()}},
    "descent": {"name": "collision_check", "arguments": {"pose": waypoint()}},
    "grasp": {"name": "finger_contacts", "arguments": {"brick_id": 2}},
    "lift": {"name": "collision_check", "arguments": {"pose": waypoint()}},
    "placement": {"name": "held_pose", "arguments": {"brick_id": 2}},
    "release": {"name": "support_contact", "arguments": {"brick_id": 2}},
    "single_agent": {"name": "held_pose", "arguments": {"brick_id": 2}},
}


@pytest.mark.parametrize("agent", sorted(TOOL_CALLS))
def test_a_tool_turn_parses_as_the_answer_model_whatever_decision_it_leaves_out(
    agent: str,
) -> None:
    step = {"step": "pre_grasp"} if agent == "single_agent" else {}
    partial = {"brick_id": 2} if agent in ("pre_grasp", "single_agent") else {}
    for answer in (step, step | partial):
        text = json.dumps({"tool_calls": [TOOL_CALLS[agent]], **answer})
        parsed = parse_answer(text, AGENTS[agent], STATE)
        assert type(parsed) is AGENTS[agent].output_model
        assert [call.name for call in parsed.tool_calls] == [TOOL_CALLS[agent]["name"]]
