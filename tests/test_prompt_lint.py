"""Prompt lint: every agent's prompt, on every built-in pattern, read as a model reads it.

No Python repr where text or JSON belongs, and every threshold a prompt names is explained
in that prompt."""

from __future__ import annotations

import re
from dataclasses import replace
from importlib import resources

import pytest
from conftest import built_state

from actionreasoning.agents.memory import PlacedBrick, TaskMemory
from actionreasoning.agents.prompt import THRESHOLDS_HEADING, render_prompt
from actionreasoning.agents.spec import AgentSpec, agent_specs, parse_agents, single_agent_spec
from actionreasoning.agents.view import StateView
from actionreasoning.world.patterns import builtin_pattern_names
from actionreasoning.world.tolerances import Tolerances

AGENTS_YAML = resources.files("actionreasoning.agents").joinpath("prompts/agents.yaml").read_text()
MEMORY = TaskMemory(
    placed=(PlacedBrick(brick_id=0, target_index=0),), current_brick=1, current_target=1
)
SPECS = {spec.number: spec for spec in (*agent_specs(), single_agent_spec())}
CASES = [(n, pattern) for n in sorted(SPECS) for pattern in builtin_pattern_names()]

#: What Python's repr of a dict, string, None or a boolean leaves in text: never a
#: model-facing form (JSON says null, true, false, and quotes with ").
PYTHON_REPR = re.compile(r"\{'|'\s*:\s*['\[{]|\bNone\b|\bTrue\b|\bFalse\b|<\w+[ .]\w+")


def rendered(spec: AgentSpec, pattern: str) -> str:
    state = built_state(pattern)
    view = StateView.of(state, MEMORY, spec.scope, spec.robot_extras)
    return render_prompt(spec, view, MEMORY, Tolerances())


def thresholds_named(prompt: str) -> list[str]:
    line = prompt.split(THRESHOLDS_HEADING + "\n", 1)[1].split("\n", 1)[0]
    return [pair.split("=", 1)[0] for pair in line.split(", ")]


@pytest.mark.parametrize(("number", "pattern"), CASES)
def test_no_python_repr_in_a_prompt(number: int, pattern: str) -> None:
    prompt = rendered(SPECS[number], pattern)
    found = [m.group(0) for m in PYTHON_REPR.finditer(prompt)]
    assert not found, found


@pytest.mark.parametrize(("number", "pattern"), [c for c in CASES if c[0] != 0])
def test_every_threshold_a_prompt_names_is_explained_there(number: int, pattern: str) -> None:
    prompt = rendered(SPECS[number], pattern)
    names = thresholds_named(prompt)
    assert names == list(SPECS[number].thresholds)
    for name in names:
        explained = re.search(rf"^- {name}: (.+)$", prompt, re.M)
        assert explained, f"{name} is named but not explained"
        assert explained.group(1) == Tolerances.model_fields[name].description


def test_the_lint_finds_a_python_dict_in_a_thinking_step() -> None:
    """The defect the issue found: a YAML step parsed as a mapping rendered as a dict."""
    broken = replace(SPECS[1], thinking=({"Target": "the first not built"},))  # type: ignore[arg-type]
    assert PYTHON_REPR.search(rendered(broken, "pyramid"))


def test_agents_yaml_with_a_step_that_is_a_mapping_is_refused_naming_it() -> None:
    text = AGENTS_YAML.replace(
        "    - >-\n      Target: the first not built", "    - Target: the first not built", 1
    )
    assert text != AGENTS_YAML
    with pytest.raises(ValueError, match=r"agent pre_grasp: a thinking step is not a line"):
        parse_agents(text)
