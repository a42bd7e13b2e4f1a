"""Agents as data and their prompts: every agent renders, a missing variable fails loudly."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest
from conftest import built_state
from jinja2 import UndefinedError
from jsonschema import Draft202012Validator

from actionreasoning.agents.memory import PlacedBrick, TaskMemory
from actionreasoning.agents.prompt import _ENVIRONMENT, render_prompt
from actionreasoning.agents.spec import AgentSpec, agent_specs, single_agent_spec
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.tolerances import Tolerances

STATE = built_state("grid")
MEMORY = TaskMemory(placed=(PlacedBrick(brick_id=0, target_index=0),), current_brick=1)


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
        assert len(spec.thinking) >= 3
        Draft202012Validator.check_schema(spec.output_model.model_json_schema())


@pytest.mark.parametrize("spec", [*agent_specs(), single_agent_spec()], ids=lambda s: s.key)
def test_every_agent_renders_its_six_parts(spec: AgentSpec) -> None:
    prompt = render_prompt(spec, STATE, MEMORY, Tolerances())
    title = f"# Agent {spec.number} of 6: {spec.name}" if spec.number else f"# {spec.name}"
    assert prompt.startswith(title + "\n")
    for heading in (
        "## Role",
        "## Current environment state S_t",
        "## Task memory M_t",
        "## Knowledge base",
        "## Thinking chain",
        "## Output format",
    ):
        assert heading in prompt
    for tool in spec.tools:
        assert f"### {tool}" in prompt
    blocks = re.findall(r"```json\n(.*?)\n```", prompt, flags=re.S)
    state, memory, schema = (json.loads(block) for block in blocks)
    assert len(state["bricks"]) == 6 and state["goal"]["name"] == "grid"
    assert memory["placed"] == [{"brick_id": 0, "target_index": 0}]
    assert schema == json.loads(json.dumps(spec.output_model.model_json_schema()))
    assert "c_min_m = 0.02" in prompt


def test_a_missing_template_variable_fails_loudly() -> None:
    template = _ENVIRONMENT.get_template("agent.md.j2")
    with pytest.raises(UndefinedError, match="role"):
        template.render(
            number=1,
            name="x",
            state_json="{}",
            memory_json="{}",
            tolerances={},
            tools=[],
            thinking=[],
            output_schema_json="{}",
        )


def test_prompt_command_prints_what_agent_one_is_sent() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "actionreasoning", "prompt", "--agent", "1", "--seed", "0"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("# Agent 1 of 6: Pre-grasp positioning")
    assert "### grasp_candidates" in result.stdout


def test_the_single_agent_merges_all_six_roles_tools_and_chains() -> None:
    merged, specs = single_agent_spec(), agent_specs()
    assert set(merged.tools) == {tool for spec in specs for tool in spec.tools}
    assert len(merged.thinking) == sum(len(spec.thinking) for spec in specs)
    for spec in specs:
        assert spec.role in merged.role
    Draft202012Validator.check_schema(merged.output_model.model_json_schema())
