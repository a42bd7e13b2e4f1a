"""The whitelist of tools: looked up by name, arguments validated before anything runs."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from pydantic import BaseModel, ValidationError

from actionreasoning.errors import ToolError
from actionreasoning.tools.base import Tool, ToolContext, ToolModel
from actionreasoning.tools.collision import COLLISION
from actionreasoning.tools.contact import FINGER_CONTACTS, SLIP
from actionreasoning.tools.deproject import DEPROJECT
from actionreasoning.tools.geometry import ALIGNMENT, SUPPORT
from actionreasoning.tools.grasp_plan import GRASP_OPTIONS
from actionreasoning.tools.placement import HELD_POSE, PLACEMENT_CHECK, PLACEMENT_POSE
from actionreasoning.tools.reach import REACHABILITY
from actionreasoning.world.geometry import MAX_COORDINATE_M, QUAT_NORM_TOLERANCE
from actionreasoning.world.models import Pose

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
        PLACEMENT_CHECK,
        DEPROJECT,
    )
}

#: The tools whose results give a brick's pose (or a pose computed from it, or its offset
#: from a target), which no agent that observes the scene in pictures gets
#: (agents/observation.py).
POSE_TOOLS: frozenset[str] = frozenset(
    {GRASP_OPTIONS.name, HELD_POSE.name, PLACEMENT_POSE.name, ALIGNMENT.name}
)

#: The check tier's tool for an agent sent pictures: a world point under a depth pixel.
PICTURE_TOOL = DEPROJECT.name

#: The gates' measurements, in no agent's knowledge base. An agent answered from outside
#: (MCP, Gymnasium) may run them whichever it is: they only read the measured world, and
#: every gate verdict reports the values they give.
GATE_MEASUREMENTS: tuple[str, ...] = (SLIP.name, ALIGNMENT.name, REACHABILITY.name)


def measurements(poses: bool) -> tuple[str, ...]:
    """The gates' measurements an outside agent may run: all of them, or, if it is shown
    no brick's pose, those that give none."""
    return tuple(name for name in GATE_MEASUREMENTS if poses or name not in POSE_TOOLS)


class ToolSchema(BaseModel):
    """A tool as a language model or an outside agent is shown it: name, what it does, and
    the JSON schemas of its arguments and of its result."""

    name: str
    description: str
    input_schema: dict[str, Any]
    output_schema: dict[str, Any]


def tool_schema(name: str) -> ToolSchema:
    """The schema of the whitelisted tool ``name``."""
    tool = TOOLS[name]
    return ToolSchema(
        name=tool.name,
        description=tool.description.strip(),
        input_schema=tool.input_model.model_json_schema(),
        output_schema=tool.output_model.model_json_schema(),
    )


def call_tool(name: str, arguments: Mapping[str, Any], context: ToolContext) -> ToolModel:
    """Run the whitelisted tool ``name`` on ``arguments`` (validated against its input model,
    and within the bounds of :func:`check_bounds`)."""
    tool = TOOLS.get(name)
    if tool is None:
        raise ToolError(f"unknown tool {name[:60]!r}; known tools: {', '.join(TOOLS)}")
    try:
        parsed = tool.input_model.model_validate(dict(arguments))
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "arguments"
        raise ToolError(f"{name}: {where}: {first['msg']}") from None
    check_bounds(parsed, name)
    return tool(context, parsed)


def check_bounds(value: Any, where: str) -> None:
    """Refuse arguments the arm model cannot take (its inverse kinematics hangs on a huge
    number and fails on a zero quaternion): every number finite, every pose within
    MAX_COORDINATE_M of the base with a unit quaternion (within QUAT_NORM_TOLERANCE)."""
    if isinstance(value, BaseModel):
        for field, item in value:
            check_bounds(item, f"{where}.{field}")
    elif isinstance(value, tuple | list):
        for index, item in enumerate(value):
            check_bounds(item, f"{where}[{index}]")
    elif isinstance(value, float) and not math.isfinite(value):
        raise ToolError(f"{where}: {value} is not a finite number")
    if isinstance(value, Pose):
        if max(abs(v) for v in value.position_m) > MAX_COORDINATE_M:
            raise ToolError(f"{where}.position_m is more than {MAX_COORDINATE_M:g} m away")
        norm = math.sqrt(sum(q * q for q in value.quat_xyzw))
        if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
            raise ToolError(f"{where}.quat_xyzw has norm {norm:.4g}: give a unit quaternion")
