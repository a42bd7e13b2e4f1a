"""Models described in a few lines for a prompt, instead of their full JSON schema.

A JSON schema spends most of its characters on structure (``$defs``, ``prefixItems``,
titles). A prompt needs each field's name, type, default and meaning: one line each,
nested models indented under the field that holds them. The schema itself still goes to
the server as the response format, and every answer is validated against it.
"""

from __future__ import annotations

import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from actionreasoning.agents.outputs import ToolCall, WaypointProposal
from actionreasoning.world.models import Pose

#: Types named rather than expanded; the prompt's conventions define them once.
NAMED: dict[type, str] = {Pose: "Pose", WaypointProposal: "Waypoint", ToolCall: "ToolCall"}


def describe_fields(model: type[BaseModel], indent: str = "") -> list[str]:
    """One line per field of ``model``: ``name: type = default  # description``."""
    lines = []
    for name, field in model.model_fields.items():
        line = f"{indent}- {name}: {type_name(field.annotation)}"
        bounds = _bounds(_constraints(field))
        if bounds:
            line += f" ({bounds})"
        if field.default is not PydanticUndefined and not field.is_required():
            line += f" = {_default(field.default)}"
        if field.description:
            line += f"  # {field.description}"
        lines.append(line)
        for nested in _nested_models(field.annotation):
            lines.extend(describe_fields(nested, indent + "  "))
    return lines


def type_name(annotation: Any) -> str:
    """A short name of a field's type."""
    if annotation in NAMED:
        return NAMED[annotation]
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return type_name(args[0])
    if origin is Literal:
        return "|".join(f'"{a}"' for a in args)
    if origin in (Union, types.UnionType):
        return " or ".join("null" if a is type(None) else type_name(a) for a in args)
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"[{type_name(args[0])}, ...]"
        if len(set(args)) == 1:
            return f"[{type_name(args[0])} x{len(args)}]"
        return "[" + ", ".join(type_name(a) for a in args) + "]"
    if origin is list:
        return f"[{type_name(args[0])}, ...]"
    if origin is dict:
        return "object"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation.__name__
    return {float: "number", int: "integer", bool: "boolean", str: "string"}.get(
        annotation, str(annotation)
    )


def _nested_models(annotation: Any) -> list[type[BaseModel]]:
    """The models (other than named ones) a field holds, each once."""
    found: list[type[BaseModel]] = []
    stack = [annotation]
    while stack:
        item = stack.pop()
        if isinstance(item, type) and issubclass(item, BaseModel):
            if item not in NAMED and item not in found:
                found.append(item)
            continue
        stack.extend(a for a in get_args(item) if a is not Ellipsis)
    return found


def _constraints(field: FieldInfo) -> list[Any]:
    """The field's constraints, and those of a constrained type it holds or null (as
    ``Index | None``)."""
    found = list(field.metadata)
    for member in get_args(field.annotation):
        if get_origin(member) is Annotated:
            for item in get_args(member)[1:]:
                found.extend(item.metadata if isinstance(item, FieldInfo) else [item])
    return found


def _bounds(metadata: list[Any]) -> str:
    """Numeric and length limits of a field, as ``>= 0``, ``<= 0.16``, ``at most 8``."""
    words = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}
    parts: list[str] = []
    for item in metadata:
        for name, relation in words.items():
            value = getattr(item, name, None)
            if value is not None:
                parts.append(f"{relation} {value:g}")
        if getattr(item, "max_length", None) is not None:
            parts.append(f"at most {item.max_length}")
    return ", ".join(parts)


def _default(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, tuple | list):
        return "[" + ", ".join(_default(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{}" if not value else str(value)
    return f"{value:g}" if isinstance(value, float) else str(value)
