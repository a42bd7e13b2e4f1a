"""The whitelist of tools: looked up by name, arguments validated before anything runs."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pydantic import ValidationError

from actionreasoning.errors import ToolError
from actionreasoning.tools.base import Tool, ToolContext, ToolModel
from actionreasoning.tools.collision import COLLISION
from actionreasoning.tools.contact import FINGER_CONTACTS, SLIP
from actionreasoning.tools.geometry import ALIGNMENT, SUPPORT
from actionreasoning.tools.grasp_plan import GRASP_OPTIONS
from actionreasoning.tools.placement import HELD_POSE, PLACEMENT_POSE
from actionreasoning.tools.reach import REACHABILITY

TOOLS: Mapping[str, Tool] = {
    tool.name: tool
    for tool in (
        ALIGNMENT,
        GRASP_OPTIONS,
        SUPPORT,
        REACHABILITY,
        COLLISION,
        FINGER_CONTACTS,
        SLIP,
        HELD_POSE,
        PLACEMENT_POSE,
    )
}


def call_tool(name: str, arguments: Mapping[str, Any], context: ToolContext) -> ToolModel:
    """Run the whitelisted tool ``name`` on ``arguments`` (validated against its input model)."""
    tool = TOOLS.get(name)
    if tool is None:
        raise ToolError(f"unknown tool {name[:60]!r}; known tools: {', '.join(TOOLS)}")
    try:
        parsed = tool.input_model.model_validate(dict(arguments))
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "arguments"
        raise ToolError(f"{name}: {where}: {first['msg']}") from None
    return tool(context, parsed)
