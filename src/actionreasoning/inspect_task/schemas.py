"""The agents' answer schemas and tools in Inspect's terms: JSON schemas as Inspect's
:class:`~inspect_ai.util.JSONSchema` (structured output) and tools as
:class:`~inspect_ai.tool.ToolInfo` (native tool calls, which the model makes and the trial
runs: Inspect never executes them).

Inspect's JSONSchema holds a subset of JSON Schema: references are inlined, a tuple's
``prefixItems`` become its ``items``, and every other keyword it lacks (``minItems``,
``exclusiveMinimum``, ...) is said in the description, so nothing the schema asks is lost;
validation (``agents/validation.py``) checks every answer in full either way.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from inspect_ai.model import ResponseSchema
from inspect_ai.tool import ToolInfo, ToolParams
from inspect_ai.util import JSONSchema

from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.spec import agent_specs, single_agent_spec
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.tools.registry import TOOLS

_DROPPED = ("title", "$defs")


def response_schema(name: str, schema: Mapping[str, Any]) -> ResponseSchema:
    """An answer's JSON schema as Inspect's structured output (not strict: a tool turn
    leaves the decision's fields out)."""
    return ResponseSchema(name=name, json_schema=inspect_schema(schema))


def inspect_schema(schema: Mapping[str, Any]) -> JSONSchema:
    """A pydantic JSON schema as Inspect's JSONSchema (see the module docstring)."""
    return JSONSchema.model_validate(_inlined(schema))


def tool_info(name: str) -> ToolInfo:
    """The whitelisted tool ``name`` as a tool the model may call."""
    tool = TOOLS[name]
    plain = _inlined(tool.input_model.model_json_schema())
    parameters = ToolParams(
        properties={key: JSONSchema.model_validate(v) for key, v in plain["properties"].items()},
        required=plain.get("required", []),
        additionalProperties=plain.get("additionalProperties", False),
    )
    return ToolInfo(name=name, description=tool.description.strip(), parameters=parameters)


def agent_tools(
    tier: ToolTier, observation: Observation = DEFAULT_OBSERVATION
) -> dict[str, tuple[ToolInfo, ...]]:
    """Each agent's tools under ``tier`` when observing ``observation``, by agent key (the
    six agents, and the single agent where it runs: observing poses)."""
    single = (single_agent_spec(tier, observation),) if observation.poses else ()
    specs = (*agent_specs(tier, observation), *single)
    return {str(spec.key): tuple(tool_info(name) for name in spec.tools) for spec in specs}


def _inlined(schema: Mapping[str, Any]) -> dict[str, Any]:
    return _plain(schema, schema.get("$defs", {}))


def _plain(node: Mapping[str, Any], defs: Mapping[str, Any]) -> dict[str, Any]:
    """``node`` with its references inlined and keywords Inspect lacks described."""
    if "$ref" in node:
        target = defs[str(node["$ref"]).rsplit("/", 1)[-1]]
        node = {**target, **{k: v for k, v in node.items() if k != "$ref"}}
    plain: dict[str, Any] = {}
    notes: list[str] = []
    for key, value in node.items():
        if key in _DROPPED:
            continue
        if key == "properties":
            plain[key] = {name: _plain(child, defs) for name, child in value.items()}
        elif key in ("items", "additionalProperties") and isinstance(value, Mapping):
            plain[key] = _plain(value, defs)
        elif key == "anyOf":
            plain[key] = [_plain(child, defs) for child in value]
        elif key == "prefixItems":
            kinds = [_plain(child, defs) for child in value]
            distinct = [kind for i, kind in enumerate(kinds) if kind not in kinds[:i]]
            plain["items"] = distinct[0] if len(distinct) == 1 else {"anyOf": distinct}
        elif key in JSONSchema.model_fields:
            plain[key] = value
        else:
            notes.append(f"{key} {value}")
    if notes:
        said = f"({', '.join(notes)})"
        plain["description"] = f"{plain['description']} {said}" if "description" in plain else said
    return plain
