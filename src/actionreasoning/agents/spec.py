"""The six agents as data, loaded from ``prompts/agents.yaml``, and the single agent.

Each agent is a role R_i, its knowledge K_i (names of tools in the whitelist, and of the
knowledge base's formulas), a thinking chain Gamma_i and an output schema Omega_i, as a
reasoning tier gives them. No class hierarchy: an agent is this record. The single-agent
ablation (number 0, ``prompts/single_agent.yaml``) holds all six roles, without gates.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from functools import cache
from importlib import resources
from typing import Any, Final, Literal

import yaml

from actionreasoning.agents import outputs
from actionreasoning.agents.knowledge import FORMULAS
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.outputs import AgentAnswer, SingleAgentAnswer
from actionreasoning.agents.tiers import DEFAULT_TIER, TIERS, ToolTier
from actionreasoning.agents.view import Scope
from actionreasoning.tools.registry import PICTURE_TOOL, POSE_TOOLS, TOOLS
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import Tolerances

#: The merged agent's key; the six agents are keyed by their stages.
SINGLE_AGENT: Final = "single_agent"
AgentKey = Stage | Literal["single_agent"]


@dataclass(frozen=True)
class AgentSpec:
    """One agent: number (1-6), key, name, role, tool names, thinking chain, output model.

    ``role`` is the task, ``gate`` what checks the answer and what follows a refusal,
    ``feedback`` the steps of the thinking chain that correct by earlier refusals (which
    only a gated agent gets, once its memory holds a refusal); ``scope`` which bricks it is
    shown, ``thresholds`` the gate thresholds it reads and ``frames`` whether its prompt
    explains the brick and tool frames, ``robot_extras`` the robot fields beyond the tool
    pose and opening it is shown.
    ``tier`` is the reasoning tier, ``formulas`` the knowledge base's formulas it is given,
    ``observation`` what it observes of the scene (``observation.py``).
    """

    number: int
    key: AgentKey
    name: str
    role: str
    gate: str
    scope: Scope
    thresholds: tuple[str, ...]
    frames: bool
    robot_extras: tuple[str, ...]
    tools: tuple[str, ...]
    thinking: tuple[str, ...]
    output_model: type[AgentAnswer]
    feedback: tuple[str, ...] = ()
    tier: ToolTier = DEFAULT_TIER
    formulas: tuple[str, ...] = ()
    observation: Observation = DEFAULT_OBSERVATION


#: In the image tier, an answer model that names a brick by id is answered without it.
_SEEN_OUTPUTS: dict[type[AgentAnswer], type[AgentAnswer]] = {
    outputs.PreGraspAnswer: outputs.PreGraspSeenAnswer
}


@cache
def agent_specs(
    tier: ToolTier = DEFAULT_TIER, observation: Observation = DEFAULT_OBSERVATION
) -> tuple[AgentSpec, ...]:
    """The six agents in pipeline order, as the reasoning tier ``tier`` gives them, observing
    ``observation``: with pictures, in the check tier, each with the ``deproject`` tool; in
    ``image`` without the tools that give a brick's pose, and agent 1 naming its brick by
    where it lies (``outputs.PreGraspSeenAnswer``)."""
    specs = parse_agents(_text("agents.yaml"), tier)
    if observation.pictures and tier is ToolTier.CHECK:
        specs = tuple(replace(spec, tools=(*spec.tools, PICTURE_TOOL)) for spec in specs)
    if not observation.poses:
        specs = tuple(
            replace(
                spec,
                tools=tuple(name for name in spec.tools if name not in POSE_TOOLS),
                output_model=_SEEN_OUTPUTS.get(spec.output_model, spec.output_model),
            )
            for spec in specs
        )
    return tuple(replace(spec, observation=observation) for spec in specs)


def _text(name: str) -> str:
    return resources.files("actionreasoning.agents").joinpath(f"prompts/{name}").read_text()


def _of_tier(value: object, tier: ToolTier, what: str) -> list[Any]:
    """A list given for every tier, or the list of ``tier`` in a mapping by tier."""
    if isinstance(value, dict):
        unknown = [key for key in value if key not in ToolTier.__members__.values()]
        if unknown:
            raise ValueError(f"{what}: unknown tiers {unknown} (tiers: {TIERS})")
        value = value.get(tier, [])
    if not isinstance(value, list):
        raise ValueError(f"{what}: give a list, or a list per tier")
    return value


def _lines(steps: list[Any], what: str) -> tuple[str, ...]:
    """Thinking steps, each a line of text (``- Target: ...`` in YAML is a mapping, which
    would render as a Python dict)."""
    if not_text := [step for step in steps if not isinstance(step, str)]:
        raise ValueError(
            f"{what}: a thinking step is not a line of text: {not_text[0]!r} "
            "(quote a step that holds ': ')"
        )
    return tuple(steps)


def _knowledge(entry: dict[str, Any], tier: ToolTier, what: str) -> tuple[tuple[str, ...], ...]:
    """The tools and formulas of an agent entry in ``tier``, checked against the whitelist
    and the formula files."""
    tools = () if tier is ToolTier.NONE else tuple(_of_tier(entry.get("tools", []), tier, what))
    formulas: tuple[str, ...] = ()
    if tier is not ToolTier.SOLVE:
        formulas = tuple(entry.get("formulas", ()))
    unknown = [name for name in tools if name not in TOOLS]
    unknown += [name for name in formulas if name not in FORMULAS]
    unknown += [name for name in entry["thresholds"] if name not in Tolerances.model_fields]
    if unknown:
        raise ValueError(f"{what} lists unknown tools, formulas or thresholds {unknown}")
    return tools, formulas


def _frames(value: object, tier: ToolTier, what: str) -> bool:
    """Whether an agent's prompt explains the frames in ``tier``: in every tier (true), none
    (false), or in the tiers listed (where it composes poses, rather than copying a
    solver's)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, list) and set(value) <= set(ToolTier):
        return tier in value
    raise ValueError(f"{what}: frames is true, false or a list of tiers ({TIERS})")


def parse_agents(text: str, tier: ToolTier = DEFAULT_TIER) -> tuple[AgentSpec, ...]:
    """The agents of an ``agents.yaml`` text in ``tier``, checked: known tools, formulas and
    thresholds, and every step of a thinking chain a line of text."""
    specs = []
    for number, entry in enumerate(yaml.safe_load(text), start=1):
        what = f"agent {entry['key']}"
        tools, formulas = _knowledge(entry, tier, what)
        for other in ToolTier:  # a defect in any tier's chain is refused in every tier
            _lines(_of_tier(entry["thinking"], other, what), what)
        specs.append(
            AgentSpec(
                number=number,
                key=Stage(entry["key"]),
                name=entry["name"],
                role=entry["role"],
                gate=entry["gate"],
                scope=Scope(entry["scope"]),
                thresholds=tuple(entry["thresholds"]),
                frames=_frames(entry["frames"], tier, what),
                robot_extras=tuple(entry.get("robot_extras", ())),
                tools=tools,
                thinking=_lines(_of_tier(entry["thinking"], tier, what), what),
                output_model=getattr(outputs, entry["output"]),
                feedback=_lines(entry.get("feedback", []), what),
                tier=tier,
                formulas=formulas,
            )
        )
    return tuple(specs)


@cache
def single_agent_spec(
    tier: ToolTier = DEFAULT_TIER, observation: Observation = DEFAULT_OBSERVATION
) -> AgentSpec:
    """The single-agent ablation: the six agents merged into one (``prompts/single_agent.yaml``
    says what it is): their roles, and their thinking chains in ``tier``, each under its
    stage's name; their tools, formulas and thresholds; no gate, and no steps that correct
    by a gate's refusals, since none refuses it. It observes the state, or the state and
    the pictures (``observation``); it names its brick by id, so never pictures alone."""
    if not observation.poses:
        raise ValueError("the single agent names its brick by id: it observes the state")
    entry = yaml.safe_load(_text("single_agent.yaml"))
    specs = agent_specs(tier, observation)
    roles = "\n".join(f"- {spec.key}: {spec.role}" for spec in specs)
    chains = tuple(f"{spec.key}: {' '.join(spec.thinking)}" for spec in specs)

    def union(names: Iterable[str]) -> tuple[str, ...]:
        return tuple(dict.fromkeys(names))

    return AgentSpec(
        number=0,
        key=SINGLE_AGENT,
        name=entry["name"],
        role=f"{entry['role']}\n{roles}",
        gate="",
        scope=Scope.ALL,
        thresholds=union(name for spec in specs for name in spec.thresholds),
        frames=True,
        robot_extras=("pad_forces_n", "ready_pose"),
        tools=union(name for spec in specs for name in spec.tools),
        thinking=chains,
        output_model=SingleAgentAnswer,
        tier=tier,
        formulas=union(name for spec in specs for name in spec.formulas),
        observation=observation,
    )
