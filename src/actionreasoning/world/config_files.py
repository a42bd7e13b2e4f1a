"""Reading the project's JSON/YAML files (patterns, physics profiles, noise levels).

Every problem becomes one line naming the file and the field, raised as the error class
the caller passes (a :class:`PatternError` for patterns, a :class:`ConfigError` else). A
file that does not parse is told by line, column and problem, never by its text (a file
may hold a secret, and the message reaches an MCP client too).
Every file a user names is read through :func:`read_user_file`: only a regular file, and
only up to a size limit, so a FIFO, a device or a huge file cannot hang or exhaust a run.
"""

from __future__ import annotations

import json
import os
import re
import stat
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any, BinaryIO, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from actionreasoning.errors import ActionReasoningError, ConfigError

M = TypeVar("M", bound=BaseModel)


def _unique_members(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object's members, refused if a key is given twice (the last would win)."""
    data: dict[str, Any] = {}
    for key, value in pairs:
        if key in data:
            raise ValueError(f"the key '{key}' is given twice")
        data[key] = value
    return data


def _json(text: str) -> Any:
    return json.loads(text, object_pairs_hook=_unique_members)


class _KeyGivenTwice(yaml.constructor.ConstructorError):
    """A mapping gives a key twice."""


class _UniqueKeyLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a mapping that gives a key twice (the last would win)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        keys = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in keys:
                raise _KeyGivenTwice(
                    None, None, f"the key '{key}' is given twice", key_node.start_mark
                )
            keys.add(key)
        return super().construct_mapping(node, deep=deep)


def _yaml(text: str) -> Any:
    return yaml.load(text, Loader=_UniqueKeyLoader)


#: A fragment PyYAML quotes in a problem, and those of them kept: a character (maybe
#: escaped) or a token's name; others (an alias, an anchor, a tag) are the file's text.
_QUOTED = re.compile(r"'(?:[^'\\]|\\.)*'|\"(?:[^\"\\]|\\.)*\"")
_KEPT = re.compile(r".|\\(?:.|x[0-9a-f]{2}|u[0-9a-f]{4}|U[0-9a-f]{8})|<[a-z ]+>")


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """What is wrong with a YAML text and where (line and column), without its lines."""
    if not isinstance(exc, yaml.MarkedYAMLError):
        return one_line(exc)  # a character the reader refuses: its code and its position
    parts = []
    for text, mark in ((exc.context, exc.context_mark), (exc.problem, exc.problem_mark)):
        if text:
            if not isinstance(exc, _KeyGivenTwice):  # the key is the problem: keep it
                text = _unquoted(text)
            where = "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"
            parts.append(one_line(text) + where)
    return "; ".join(parts)


def _unquoted(problem: str) -> str:
    """``problem`` with each fragment of the file it quotes left out, but a character or a
    token's name."""
    return _QUOTED.sub(lambda q: q[0] if _KEPT.fullmatch(q[0][1:-1]) else "'...'", problem)


_PARSERS: dict[str, tuple[str, Callable[[str], Any]]] = {
    ".json": ("JSON", _json),
    ".yaml": ("YAML", _yaml),
    ".yml": ("YAML", _yaml),
}


#: The largest pattern, physics, noise or run file read.
MAX_FILE_BYTES = 1 << 20
_CHUNK = 1 << 20

_KINDS = {
    stat.S_IFDIR: "a directory",
    stat.S_IFIFO: "a FIFO",
    stat.S_IFCHR: "a character device",
    stat.S_IFBLK: "a block device",
    stat.S_IFSOCK: "a socket",
}


#: The longest file name (one path component) and path the system opens, in bytes.
NAME_MAX, PATH_MAX = 255, 4095


def check_file_name(
    name_or_path: str | Path, argument: str, error: type[ActionReasoningError] = ConfigError
) -> None:
    """Refuse, in one ``error`` line naming ``argument``, a name or path no file can have:
    an empty one (not taken as the current directory), one with a NUL byte, one the file
    system cannot encode, one too long to open (said by its length, not printed whole)."""
    text = str(name_or_path)
    if not text:
        raise error(f"{argument}: empty")
    if "\0" in text:
        raise error(f"{argument}: contains a NUL byte")
    try:
        encoded = os.fsencode(text)
    except UnicodeEncodeError as exc:
        raise error(f"{argument}: not a valid file name ({one_line(exc.reason)})") from exc
    if len(encoded) > PATH_MAX or any(len(part) > NAME_MAX for part in encoded.split(b"/")):
        raise error(f"{argument}: file name too long ({len(text)} characters)")


def read_user_file(
    path: Path,
    what: str,
    error: type[ActionReasoningError] = ConfigError,
    limit: int | None = MAX_FILE_BYTES,
) -> bytes:
    """The bytes of the ``what`` file (e.g. "pattern file") at ``path``, a regular file
    (symlinks followed) of at most ``limit`` bytes (None: no limit); else a one-line ``error``.

    Opening does not block (a FIFO without a writer opens at once and is then refused).
    """
    with open_user_file(path, what, error) as handle:
        try:
            data = _read(handle.fileno(), limit)
        except OSError as exc:
            raise error(f"{path}: cannot read {what} ({one_line(exc.strerror or exc)})") from exc
    if limit is not None and len(data) > limit:
        raise error(f"{path}: cannot read {what} (larger than {_size(limit)})")
    return data


def open_user_file(
    path: Path, what: str, error: type[ActionReasoningError] = ConfigError
) -> BinaryIO:
    """The ``what`` file at ``path`` opened to read in binary, if it is a regular file
    (symlinks followed); else a one-line ``error``. Opening does not block (a FIFO without
    a writer opens at once and is then refused). Errors while reading are the caller's. A
    path no file can have is refused by its length, not printed whole."""
    check_file_name(path, what, error)
    try:
        descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as exc:
        raise error(f"{path}: cannot read {what} ({one_line(exc.strerror or exc)})") from exc
    try:
        mode = os.fstat(descriptor).st_mode
        if not stat.S_ISREG(mode):
            kind = _KINDS.get(stat.S_IFMT(mode), "not a file")
            raise error(f"{path}: cannot read {what} ({kind}, not a regular file)")
        return os.fdopen(descriptor, "rb")
    except OSError as exc:
        os.close(descriptor)
        raise error(f"{path}: cannot read {what} ({one_line(exc.strerror or exc)})") from exc
    except BaseException:
        os.close(descriptor)
        raise


def _read(descriptor: int, limit: int | None) -> bytes:
    """Everything in the open file, or (past ``limit`` bytes) enough to tell it is larger."""
    chunks: list[bytes] = []
    total = 0
    while limit is None or total <= limit:
        chunk = os.read(descriptor, _CHUNK)
        if not chunk:
            break
        chunks.append(chunk)
        total += len(chunk)
    return b"".join(chunks)


def _size(limit: int) -> str:
    return f"{limit >> 20} MiB" if limit % (1 << 20) == 0 else f"{limit} bytes"


def one_line(text: object) -> str:
    """``text`` with every run of whitespace (newlines too) turned into one space."""
    return " ".join(str(text).split())


def read_mapping(path: Path, what: str, error: type[ActionReasoningError]) -> dict[str, Any]:
    """The top-level mapping of a JSON or YAML ``what`` file (e.g. "pattern file")."""
    suffix = path.suffix.lower()
    if suffix not in _PARSERS:
        raise error(f"{path}: unknown extension '{suffix}' (use .json, .yaml or .yml)")
    kind, parse = _PARSERS[suffix]
    raw = read_user_file(path, what, error)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: cannot read {what} ({one_line(exc)})") from exc
    try:
        data = parse(text)
    except RecursionError as exc:
        raise error(f"{path}: not valid {kind} (nested too deeply)") from exc
    except yaml.YAMLError as exc:
        raise error(f"{path}: not valid {kind} ({_yaml_problem(exc)})") from exc
    except ValueError as exc:  # JSON's, which quote no text of the file
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
            f"{source}: {field.lstrip('.') or 'file'}: {one_line(first['msg'])}"
            f"{_yaml_number_hint(first.get('input'))}{more}"
        ) from exc


def _yaml_number_hint(value: object) -> str:
    """For a number YAML read as text (its 1.1 rules want a point and a signed exponent:
    1.0e+6, not 1.0e6 or 1e+6), how to write it; else nothing."""
    if not isinstance(value, str) or "e" not in value.lower():
        return ""
    try:
        float(value)
    except ValueError:
        return ""
    mantissa, _, exponent = value.lower().partition("e")
    signed = exponent if exponent[:1] in "+-" else f"+{exponent}"
    if "." not in mantissa:
        mantissa += ".0"
    return f" ('{value}' is read as text by YAML: write {mantissa}e{signed})"


def load_named(name_or_path: str | Path, builtins: Mapping[str, M], model: type[M], what: str) -> M:
    """A built-in ``what`` (e.g. "physics profile") by name, or a file of ``model``.

    A file may not reuse a built-in's name with other values: runs are told apart by name.
    """
    if isinstance(name_or_path, str) and name_or_path in builtins:
        return builtins[name_or_path]
    check_file_name(name_or_path, what.split()[0])
    path = Path(name_or_path)
    if not path.exists() and path.suffix == "":
        raise ConfigError(
            f"unknown {what} '{name_or_path}' (known: {', '.join(builtins)}, or a .json/.yaml file)"
        )
    kind = what.split()[-1]  # "profile", "level"
    data = read_mapping(path, f"{what.split()[0]} file", ConfigError)
    loaded = parse_model(model, data, str(path), ConfigError)
    name = loaded.name  # type: ignore[attr-defined]  # every named model (profile, level) has one
    if name in builtins and loaded != builtins[name]:
        raise ConfigError(
            f"{path}: name: '{name}' is a built-in {kind} with other values; "
            f"give this {kind} a name of its own"
        )
    return loaded
