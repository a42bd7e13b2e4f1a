"""Agents as data and their prompts: every agent renders, a missing variable fails loudly,
and a prompt says what is true: frames with a worked example, tool results with their
fields, the thresholds its agent reads, and for the single agent nothing of the gates."""

from __future__ import annotations

import math
import re

import pytest
from conftest import built_state, cli
from jinja2 import UndefinedError
from jsonschema import Draft202012Validator

from actionreasoning.agents.feedback import Refusal
from actionreasoning.agents.memory import PlacedBrick, TaskMemory
from actionreasoning.agents.prompt import _ENVIRONMENT, DIGITS, THRESHOLD_LINE, render_prompt
from actionreasoning.agents.spec import AgentSpec, agent_specs, single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.geometry import round_floats, top_down_quat
from actionreasoning.world.tolerances import Tolerances

STATE = built_state("grid")
MEMORY = TaskMemory(
    placed=(PlacedBrick(brick_id=0, target_index=0),), current_brick=1, current_target=1
)


def _prompt(spec: AgentSpec) -> str:
    view = StateView.of(STATE, MEMORY, spec.scope, spec.robot_extras)
    return render_prompt(spec, view, MEMORY, Tolerances())


def test_there_are_six_agents_with_known_tools_and_valid_output_schemas() -> None:
    specs = agent_specs()
    assert [s.key for s in specs] == [
        "pre_grasp",
        "descent",
        "grasp",
        "lift",
        "placement",
        "release",
    ]
    for spec in specs:
        assert spec.tools and set(spec.tools) <= set(TOOLS)
        assert spec.thinking and spec.gate
        assert set(spec.thresholds) <= set(Tolerances.model_fields)
        Draft202012Validator.check_schema(spec.output_model.model_json_schema())


@pytest.mark.parametrize("spec", [*agent_specs(), single_agent_spec()], ids=lambda s: s.key)
def test_every_agent_renders_its_parts_and_its_state_reads_back(spec: AgentSpec) -> None:
    prompt = _prompt(spec)
    title = f"# Agent {spec.number} of 6: {spec.name}" if spec.number else f"# {spec.name}"
    assert prompt.startswith(title + "\n")
    for heading in ("## Conventions", "## Role", "## State S_t", "## Memory M_t", "## Tools"):
        assert heading in prompt
    for heading in ("## Thresholds", "## Thinking chain", "## Answer"):
        assert heading in prompt
    for tool in spec.tools:
        assert f"### {tool}: " in prompt
    state_json, memory_json = re.findall(r"```json\n(.*?)\n```", prompt, flags=re.S)
    shown = StateView.of(STATE, MEMORY, spec.scope, spec.robot_extras).model_dump(mode="json")
    assert StateView.model_validate_json(state_json) == StateView.model_validate(
        round_floats(shown, DIGITS)
    )
    shown_memory = TaskMemory.model_validate_json(memory_json)
    unread = {"placed", "step"} if spec.number > 1 else {"step"} if spec.number else set()
    defaults = {name: TaskMemory.model_fields[name].default for name in unread}
    assert shown_memory == MEMORY.model_copy(update=defaults)
    section = prompt.split("## Thresholds\n", 1)[1].split("\n\n", 1)[0]
    assert [name for name, _, _ in THRESHOLD_LINE.findall(section)] == list(spec.thresholds)


def test_tool_results_are_described_field_by_field() -> None:
    placement = _prompt(agent_specs(ToolTier.CHECK)[4])
    result = placement.split("### held_pose: ", 1)[1].split("Result:\n", 1)[1]
    assert "- offset_in_hand_m: [number x3]  # Centre, tool frame." in result
    assert "- slot_pose: Pose" in _prompt(agent_specs(ToolTier.SOLVE)[4])
    assert '"$defs"' not in placement  # no raw JSON schema


def test_the_tool_quaternion_the_conventions_give_is_the_codes() -> None:
    prompt = _prompt(agent_specs()[1])
    assert "Pointing down at yaw a, its quaternion is\n  [cos(a/2), sin(a/2), 0, 0]" in prompt
    for degrees in (-150.0, 0.0, 30.0, 96.7):
        yaw = math.radians(degrees)
        assert top_down_quat(yaw) == pytest.approx(
            [math.cos(yaw / 2), math.sin(yaw / 2), 0, 0], abs=1e-12
        )


def test_the_single_agent_is_the_six_agents_merged_and_told_nothing_else_checks_it() -> None:
    for tier in ToolTier:
        merged, specs = single_agent_spec(tier), agent_specs(tier)
        prompt = _prompt(merged)
        assert "nothing else checks it, before or after it runs" in prompt
        for spec in specs:
            assert spec.gate not in prompt
            assert f"- {spec.key}: {spec.role}" in prompt
            assert f"{spec.key}: {' '.join(spec.thinking)}" in merged.thinking
        assert set(merged.tools) == {tool for spec in specs for tool in spec.tools}
        assert set(merged.formulas) == {name for spec in specs for name in spec.formulas}
        assert set(merged.thresholds) == {name for spec in specs for name in spec.thresholds}
        steps = [step.split(":", 1)[0] for step in merged.thinking]
        assert steps == [str(spec.key) for spec in specs]


def test_the_single_agent_is_told_of_no_gate_and_no_refusal() -> None:
    for tier in ToolTier:
        prompt = _prompt(single_agent_spec(tier))
        assert "sigma" not in prompt.lower()
        assert "refusal" not in prompt


def test_a_missing_template_variable_fails_loudly() -> None:
    template = _ENVIRONMENT.get_template("agent.md.j2")
    with pytest.raises(UndefinedError, match="conventions"):
        template.render(number=1, name="x")


@pytest.mark.slow  # trial 0 runs in the simulator until agent 6 is asked
def test_prompt_command_prints_what_an_agent_is_sent_in_trial_zero() -> None:
    result = cli("prompt", "--agent", "6", "--seed", "0")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("# Agent 6 of 6: Release and return")
    memory = re.findall(r"```json\n(.*?)\n```", result.stdout, flags=re.S)[1]
    done = TaskMemory.model_validate_json(memory).this_brick
    assert [(m.agent, m.phase) for m in done] == [
        ("pre_grasp", None),
        ("descent", None),
        ("grasp", None),
        ("lift", None),
        ("placement", "carry"),
        ("placement", "set_down"),
    ]
    assert done[0].brick_id == 0 and done[0].waypoint is not None and done[2].close
    assert all(m.passed and not m.failed for m in done)
    assert '"passed":true' in memory and "failed" not in memory
    assert '"ready_pose":{"position_m":[0.45,-0.25,0.4]' in result.stdout


@pytest.mark.parametrize("tier", list(ToolTier))
def test_the_steps_that_correct_by_refusals_come_with_the_first_refusal(tier: ToolTier) -> None:
    spec = agent_specs(tier)[4]  # placement: two feedback steps
    refused = MEMORY.model_copy(
        update={"refusals": (Refusal(agent="placement", gate="sigma5_placement"),)}
    )
    view = StateView.of(STATE, MEMORY, spec.scope, spec.robot_extras)
    before = render_prompt(spec, view, MEMORY, Tolerances())
    after = render_prompt(spec, view, refused, Tolerances())
    assert spec.feedback
    for step in spec.feedback:
        assert step not in before
        assert step in after
