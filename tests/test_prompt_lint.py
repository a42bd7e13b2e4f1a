"""Prompt lint: every agent's prompt, in every reasoning tier, on every built-in pattern,
read as a model reads it.

No Python repr where text or JSON belongs; every threshold a prompt names is explained in
it; every answer field a thinking chain names is in the agent's answer schema; every
decimal number in the prose carries its unit; every frame used is defined; and the single
agent's prompt is free of the contradictions issue 26 found (one test each)."""

from __future__ import annotations

import re
from dataclasses import replace
from importlib import resources
from typing import get_args

import pytest
from conftest import built_state

from actionreasoning.agents.memory import PlacedBrick, TaskMemory
from actionreasoning.agents.outputs import SingleAgentStep
from actionreasoning.agents.prompt import THRESHOLD_LINE, THRESHOLDS_HEADING, render_prompt
from actionreasoning.agents.spec import AgentSpec, agent_specs, parse_agents, single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.world.scenarios import PATTERNS
from actionreasoning.world.tolerances import Tolerances

AGENTS_YAML = resources.files("actionreasoning.agents").joinpath("prompts/agents.yaml").read_text()
MEMORY = TaskMemory(
    placed=(PlacedBrick(brick_id=0, target_index=0),), current_brick=1, current_target=1
)


def specs(tier: ToolTier) -> dict[int, AgentSpec]:
    return {spec.number: spec for spec in (*agent_specs(tier), single_agent_spec(tier))}


CASES = [
    (tier, number, pattern) for tier in ToolTier for number in range(7) for pattern in PATTERNS
]

#: What Python's repr of a dict, string, None or a boolean leaves in text: never a
#: model-facing form (JSON says null, true, false, and quotes with ").
PYTHON_REPR = re.compile(r"\{'|'\s*:\s*['\[{]|\bNone\b|\bTrue\b|\bFalse\b|<\w+[ .]\w+")
#: The fields a thinking step tells the agent to answer: names (a list of them) right after
#: "answer", ended by ':', '=', ',', '.' or ' and'.
ANSWERED = re.compile(r"\b[Aa]nswer ([a-z][a-z_]*(?:(?:, | and )[a-z][a-z_]*)*)(?=:| =|,|\.| and)")
#: A decimal number in prose and what follows it.
DECIMAL = re.compile(r"(?<![\w.\[,-])(\d+\.\d+)(\s*\S*)")
UNITS = ("m", "m/s", "m,", "m)", "m;", "m.", "s", "s,", "s.", "deg", "N", "m/s,", "m/s.", "m/s)")


def rendered(spec: AgentSpec, pattern: str) -> str:
    state = built_state(pattern)
    view = StateView.of(state, MEMORY, spec.scope, spec.robot_extras)
    return render_prompt(spec, view, MEMORY, Tolerances())


def prose(spec: AgentSpec) -> str:
    """What an agent's prompt says in words: role, gate and thinking chain (the formulas'
    numbers are the worked examples' data, rendered from code)."""
    return "\n".join([spec.role, spec.gate, *spec.thinking, *spec.feedback])


def thresholds_explained(prompt: str) -> dict[str, str]:
    """Each threshold under the thresholds heading, with what the prompt says it bounds."""
    section = prompt.split(THRESHOLDS_HEADING + "\n", 1)[1].split("\n\n", 1)[0]
    return {name: text for name, _, text in THRESHOLD_LINE.findall(section)}


@pytest.mark.parametrize(("tier", "number", "pattern"), CASES)
def test_no_python_repr_in_a_prompt(tier: ToolTier, number: int, pattern: str) -> None:
    prompt = rendered(specs(tier)[number], pattern)
    found = [m.group(0) for m in PYTHON_REPR.finditer(prompt)]
    assert not found, found


@pytest.mark.parametrize(("tier", "number", "pattern"), CASES)
def test_every_threshold_a_prompt_names_is_explained_there(
    tier: ToolTier, number: int, pattern: str
) -> None:
    spec = specs(tier)[number]
    prompt = rendered(spec, pattern)
    explained = thresholds_explained(prompt)
    names = list(explained)
    assert names == list(spec.thresholds)
    for name, text in explained.items():
        assert text == Tolerances.model_fields[name].description, f"{name} is not explained"
    used = set(re.findall(r"\b([a-z]+(?:_[a-z]+)*_(?:m|deg|n|mps|factor))\b", prose(spec)))
    unexplained = {n for n in used & set(Tolerances.model_fields) if n not in names}
    assert not unexplained, f"the prose uses thresholds it does not list: {unexplained}"


@pytest.mark.parametrize(("tier", "number"), [(t, n) for t in ToolTier for n in range(7)])
def test_every_answer_field_a_thinking_chain_names_is_in_the_schema(
    tier: ToolTier, number: int
) -> None:
    spec = specs(tier)[number]
    fields = set(spec.output_model.model_fields)
    named = set()
    for step in (*spec.thinking, *spec.feedback):
        # "Answer brick_id, target_index and waypoint: ...", "answer regrasp.", "close = true"
        for listed in ANSWERED.findall(step):
            named |= set(re.split(r", | and ", listed))
        named |= set(re.findall(r"\b(gripper) \"\w+\"", step))
    assert named, "the thinking chain names no answer field"
    assert named <= fields, f"not fields of {spec.output_model.__name__}: {named - fields}"


@pytest.mark.parametrize(("tier", "number"), [(t, n) for t in ToolTier for n in range(7)])
def test_every_decimal_number_in_the_prose_carries_its_unit(tier: ToolTier, number: int) -> None:
    spec = specs(tier)[number]
    bare = [
        number + after
        for number, after in DECIMAL.findall(prose(spec))
        if not after.strip().startswith(UNITS)
    ]
    assert not bare, f"numbers without a unit: {bare}"


@pytest.mark.parametrize(("tier", "number"), [(t, n) for t in ToolTier for n in range(7)])
def test_every_frame_a_prompt_uses_is_defined_in_it(tier: ToolTier, number: int) -> None:
    prompt = rendered(specs(tier)[number], "pyramid")
    if "tool frame" in prompt:
        assert "The tool pose is the point between the pads" in prompt, "tool frame undefined"
    assert "World frame: origin at the arm's base" in prompt


def test_no_prompt_speaks_of_speeds_in_cm_per_s() -> None:
    """Agent 4 gave the lift speed in cm/s but computed durations with metres."""
    for tier in ToolTier:
        for spec in specs(tier).values():
            assert "cm/s" not in rendered(spec, "pyramid"), spec.name


def test_a_duration_says_distance_from_what() -> None:
    """'duration_s = its distance / 0.1 m/s' did not say distance from what."""
    for tier in ToolTier:
        for spec in specs(tier).values():
            for step in (*spec.thinking, *spec.feedback):
                if "duration_s =" in step:
                    assert re.search(r"distance \(m\) from the tool's position|the tool's z", step)


# --- the single agent's contradictions, one test each ------------------------------------
SINGLE = {tier: single_agent_spec(tier) for tier in ToolTier}


@pytest.mark.parametrize("tier", list(ToolTier))
def test_single_agent_answers_every_stage_by_its_agents_chain(tier: ToolTier) -> None:
    """The merged prompt names each step it may answer once, in order, with the chain of that
    stage's agent: what the built-in single agent runs."""
    steps = [str(step) for step in get_args(SingleAgentStep)]
    named = [s.split(":", 1)[0] for s in SINGLE[tier].thinking]
    assert named == steps == [str(spec.key) for spec in agent_specs(tier)]


@pytest.mark.parametrize("tier", list(ToolTier))
def test_single_agent_explains_every_threshold_without_a_gate(tier: ToolTier) -> None:
    """10 of its 13 thresholds were listed but never explained; it has no gate."""
    explained = thresholds_explained(rendered(SINGLE[tier], "pyramid"))
    assert list(explained) == list(SINGLE[tier].thresholds)
    for text in explained.values():
        assert text and "sigma" not in text
    assert "sigma_" not in prose(SINGLE[tier])


def test_the_lint_finds_a_python_dict_in_a_thinking_step() -> None:
    """The defect the issue found: a YAML step parsed as a mapping rendered as a dict."""
    spec = specs(ToolTier.CHECK)[1]
    broken = replace(spec, thinking=({"Target": "the first not built"},))  # type: ignore[arg-type]
    assert PYTHON_REPR.search(rendered(broken, "pyramid"))


def test_agents_yaml_with_a_step_that_is_a_mapping_is_refused_naming_it() -> None:
    text = AGENTS_YAML.replace(
        "      - >-\n        Target: the first not built", "      - Target: the first not built", 1
    )
    assert text != AGENTS_YAML
    with pytest.raises(ValueError, match=r"agent pre_grasp: a thinking step is not a line"):
        parse_agents(text, ToolTier.CHECK)


def test_agents_yaml_with_an_unknown_tier_is_refused_naming_it() -> None:
    text = AGENTS_YAML.replace("    check: [collision_check, reachability]", "    chek: []", 1)
    assert text != AGENTS_YAML
    with pytest.raises(ValueError, match=r"agent pre_grasp.*unknown tiers \['chek'\]"):
        parse_agents(text, ToolTier.CHECK)
