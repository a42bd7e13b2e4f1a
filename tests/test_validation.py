"""A model's answer is data: parsed, validated and bounded before anything can use it."""

from __future__ import annotations

import json
import math

import pytest
from conftest import built_state

from actionreasoning.agents.outputs import DescentAnswer, PlacementAnswer, PreGraspAnswer
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.validation import OutputError, parse_answer
from actionreasoning.world.geometry import top_down_quat

STATE = built_state("pyramid")
AGENTS = {spec.key: spec for spec in agent_specs()}
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
