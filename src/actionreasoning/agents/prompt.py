"""Prompt rendering: <S_t, M_t, R_i, K_i, Gamma_i, Omega_i> through a template file.

The template is rendered with Jinja's StrictUndefined, so a missing variable is an error,
never an empty hole in a prompt. Numbers in the state are rounded to 0.01 mm / 1e-5 rad so
that prompts stay short without losing what the gates measure.
"""

from __future__ import annotations

import json
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.spec import AgentSpec
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.models import WorldState
from actionreasoning.world.tolerances import Tolerances

DIGITS = 5
_ENVIRONMENT = Environment(
    loader=PackageLoader("actionreasoning.agents", "prompts"),
    undefined=StrictUndefined,
    keep_trailing_newline=True,
    autoescape=False,
)


def _rounded(value: Any) -> Any:
    if isinstance(value, float):
        return round(value, DIGITS) + 0.0  # + 0.0 turns -0.0 into 0.0
    if isinstance(value, list | tuple):
        return [_rounded(v) for v in value]
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    return value


def compact_json(data: Any) -> str:
    """Compact JSON with floats rounded as in prompts."""
    return json.dumps(_rounded(data), separators=(",", ":"))


def render_prompt(
    spec: AgentSpec, state: WorldState, memory: TaskMemory, tolerances: Tolerances
) -> str:
    """The full prompt of agent ``spec`` for this state and memory."""
    template = _ENVIRONMENT.get_template("agent.md.j2")
    tools = [
        {
            "name": name,
            "description": TOOLS[name].description,
            "schema_json": compact_json(TOOLS[name].input_model.model_json_schema()),
        }
        for name in spec.tools
    ]
    return template.render(
        number=spec.number,
        name=spec.name,
        role=spec.role,
        state_json=compact_json(state.model_dump(mode="json")),
        memory_json=compact_json(memory.model_dump(mode="json")),
        tolerances=tolerances.model_dump(),
        tools=tools,
        thinking=spec.thinking,
        output_schema_json=compact_json(spec.output_model.model_json_schema()),
    )
