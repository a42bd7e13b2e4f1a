"""Reading the project's JSON/YAML files (patterns, physics profiles, noise levels).

Every problem becomes one line naming the file and the field, raised as the error class
the caller passes (a :class:`PatternError` for patterns, a :class:`ConfigError` else).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from actionreasoning.errors import ActionReasoningError, ConfigError

M = TypeVar("M", bound=BaseModel)

_PARSERS = {
    ".json": ("JSON", json.loads),
    ".yaml": ("YAML", yaml.safe_load),
    ".yml": ("YAML", yaml.safe_load),
}


def one_line(text: object) -> str:
    """``text`` with every run of whitespace (newlines too) turned into one space."""
    return " ".join(str(text).split())


def read_mapping(path: Path, what: str, error: type[ActionReasoningError]) -> dict[str, Any]:
    """The top-level mapping of a JSON or YAML ``what`` file (e.g. "pattern file")."""
    suffix = path.suffix.lower()
    if suffix not in _PARSERS:
        raise error(f"{path}: unknown extension '{suffix}' (use .json, .yaml or .yml)")
    kind, parse = _PARSERS[suffix]
    try:
        data = parse(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:  # first: UnicodeDecodeError is a ValueError
        reason = one_line(getattr(exc, "strerror", None) or exc)
        raise error(f"{path}: cannot read {what} ({reason})") from exc
    except (ValueError, yaml.YAMLError) as exc:
        raise error(f"{path}: not valid {kind} ({one_line(exc)})") from exc
    if not isinstance(data, dict):
        raise error(f"{path}: top level must be a mapping, not {type(data).__name__}")
    return data


def parse_model(
    model: type[M], data: dict[str, Any], source: str, error: type[ActionReasoningError]
) -> M:
    """Validate raw data as ``model``; the first pydantic error becomes one line."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        first = errors[0]
        field = "".join(f"[{p}]" if isinstance(p, int) else f".{p}" for p in first["loc"])
        more = f" (and {len(errors) - 1} more)" if len(errors) > 1 else ""
        raise error(
            f"{source}: {field.lstrip('.') or 'file'}: {one_line(first['msg'])}{more}"
        ) from exc


def load_named(name_or_path: str | Path, builtins: Mapping[str, M], model: type[M], what: str) -> M:
    """A built-in ``what`` (e.g. "physics profile") by name, or a file of ``model``.

    A file may not reuse a built-in's name with other values: runs are told apart by name.
    """
    if isinstance(name_or_path, str) and name_or_path in builtins:
        return builtins[name_or_path]
    path = Path(name_or_path)
    if not path.exists() and path.suffix == "":
        raise ConfigError(
            f"unknown {what} '{name_or_path}' (known: {', '.join(builtins)}, or a .json/.yaml file)"
        )
    kind = what.split()[-1]  # "profile", "level"
    data = read_mapping(path, f"{what.split()[0]} file", ConfigError)
    loaded = parse_model(model, data, str(path), ConfigError)
    name = loaded.name  # type: ignore[attr-defined]
    if name in builtins and loaded != builtins[name]:
        raise ConfigError(
            f"{path}: name: '{name}' is a built-in {kind} with other values; "
            f"give this {kind} a name of its own"
        )
    return loaded
