"""The six agents as data, loaded from ``prompts/agents.yaml``.

Each agent is a role R_i, the names of its tools K_i (all in the tool whitelist), a thinking
chain Gamma_i and an output schema Omega_i. No class hierarchy: an agent is this record.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from importlib import resources

import yaml

from actionreasoning.agents import outputs
from actionreasoning.agents.outputs import AgentAnswer
from actionreasoning.tools.registry import TOOLS


@dataclass(frozen=True)
class AgentSpec:
    """One agent: number (1-6), key, name, role, tool names, thinking chain, output model."""

    number: int
    key: str
    name: str
    role: str
    tools: tuple[str, ...]
    thinking: tuple[str, ...]
    output_model: type[AgentAnswer]


@cache
def agent_specs() -> tuple[AgentSpec, ...]:
    """The six agents in pipeline order."""
    text = resources.files("actionreasoning.agents").joinpath("prompts/agents.yaml").read_text()
    specs = []
    for number, entry in enumerate(yaml.safe_load(text), start=1):
        unknown = [name for name in entry["tools"] if name not in TOOLS]
        if unknown:
            raise ValueError(f"agent {entry['key']} lists unknown tools {unknown}")
        specs.append(
            AgentSpec(
                number=number,
                key=entry["key"],
                name=entry["name"],
                role=entry["role"],
                tools=tuple(entry["tools"]),
                thinking=tuple(entry["thinking"]),
                output_model=getattr(outputs, entry["output"]),
            )
        )
    return tuple(specs)
