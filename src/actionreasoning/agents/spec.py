"""The six agents as data, loaded from ``prompts/agents.yaml``, and their merger.

Each agent is a role R_i, the names of its tools K_i (all in the tool whitelist), a thinking
chain Gamma_i and an output schema Omega_i. No class hierarchy: an agent is this record.
The single-agent ablation merges all six into one (number 0).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources
from typing import Final, Literal

import yaml

from actionreasoning.agents import outputs
from actionreasoning.agents.outputs import AgentAnswer, SingleAgentAnswer
from actionreasoning.agents.view import Scope
from actionreasoning.tools.registry import TOOLS
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
    only a gated agent gets); ``scope`` which bricks it is shown, ``thresholds`` the gate
    thresholds it reads and ``frames`` whether its prompt explains the brick and tool
    frames, ``robot_extras`` the robot fields beyond the tool pose and opening it is shown.
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


@cache
def agent_specs() -> tuple[AgentSpec, ...]:
    """The six agents in pipeline order."""
    text = resources.files("actionreasoning.agents").joinpath("prompts/agents.yaml").read_text()
    return parse_agents(text)


def parse_agents(text: str) -> tuple[AgentSpec, ...]:
    """The agents of an ``agents.yaml`` text, checked: known tools and thresholds, and every
    step of a thinking chain a line of text (``- Target: ...`` in YAML is a mapping, which
    would render as a Python dict)."""
    specs = []
    for number, entry in enumerate(yaml.safe_load(text), start=1):
        unknown = [name for name in entry["tools"] if name not in TOOLS]
        unknown += [name for name in entry["thresholds"] if name not in Tolerances.model_fields]
        if unknown:
            raise ValueError(f"agent {entry['key']} lists unknown tools or thresholds {unknown}")
        steps = [*entry["thinking"], *entry.get("feedback", ())]
        if not_text := [step for step in steps if not isinstance(step, str)]:
            raise ValueError(
                f"agent {entry['key']}: a thinking step is not a line of text: {not_text[0]!r} "
                "(quote a step that holds ': ')"
            )
        specs.append(
            AgentSpec(
                number=number,
                key=Stage(entry["key"]),
                name=entry["name"],
                role=entry["role"],
                gate=entry["gate"],
                scope=Scope(entry["scope"]),
                thresholds=tuple(entry["thresholds"]),
                frames=entry["frames"],
                robot_extras=tuple(entry.get("robot_extras", ())),
                tools=tuple(entry["tools"]),
                thinking=tuple(entry["thinking"]),
                output_model=getattr(outputs, entry["output"]),
                feedback=tuple(entry.get("feedback", ())),
            )
        )
    return tuple(specs)


#: The single agent's task-memory step before its first waypoint.
SINGLE_AGENT_START: Final = "start"
SINGLE_AGENT_CYCLE = (
    "Per brick, answer one waypoint per call in this order: pre_grasp (name brick_id and "
    "target_index; the approach pose above the brick, then open the gripper), descent (straight "
    "down to the grasp pose), grasp (close), lift (straight up), transfer (above the target "
    "slot), placement (down onto the slot), release (open), retreat (straight up). After the "
    "last brick answer done, with the ready pose as waypoint. Memory's step is the step "
    "executed last. Nothing checks your waypoints before they run and nothing is retried: "
    "each answer runs as given, a brick that slips stays where it falls, and a pose the arm "
    "cannot reach ends the build."
)


@cache
def single_agent_spec() -> AgentSpec:
    """All six roles, tools and thinking chains merged into one agent (the ablation)."""
    specs = agent_specs()
    tools = tuple(dict.fromkeys(name for spec in specs for name in spec.tools))
    role = "\n\n".join([SINGLE_AGENT_CYCLE, *(f"{s.name}: {s.role}" for s in specs)])
    thinking = tuple(f"{spec.name}: {step}" for spec in specs for step in spec.thinking)
    return AgentSpec(
        number=0,
        key=SINGLE_AGENT,
        name="Single agent (all six roles merged)",
        role=role,
        gate="",
        scope=Scope.ALL,
        thresholds=tuple(dict.fromkeys(name for spec in specs for name in spec.thresholds)),
        frames=True,
        robot_extras=("pad_forces_n", "ready_pose"),
        tools=tools,
        thinking=thinking,
        output_model=SingleAgentAnswer,
    )
