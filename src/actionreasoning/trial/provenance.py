"""Which code wrote a record: the format's version, the package's, its git revision and the
simulator's. Every results.jsonl line and summary.json carries these fields.

They are found once per run, in the process that writes the files, and stamped on each
record as it is written: a trial run in a worker or on a Ray cluster gets the same values.
"""

from __future__ import annotations

import subprocess
from importlib import metadata
from pathlib import Path
from typing import TypeVar

from pydantic import BaseModel, ConfigDict, PositiveInt

#: The version of the results.jsonl and summary.json formats: 2 added these fields (lines
#: without them are of version 1, and are read as such).
SCHEMA_VERSION = 2
GIT_TIMEOUT_S = 10.0

Record = TypeVar("Record", bound=BaseModel)


class Provenance(BaseModel):
    """The fields that say which code wrote a record; None in a record of version 1, and
    ``git_revision`` None where the package does not run from a git checkout."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    schema_version: PositiveInt | None = None
    package_version: str | None = None
    git_revision: str | None = None
    pybullet_version: str | None = None


def stamp(record: Record, provenance: Provenance) -> Record:
    """``record`` (a model with the fields of :class:`Provenance`) with them set."""
    return record.model_copy(update=provenance.model_dump())


def current_provenance() -> Provenance:
    """This process's code: the installed versions and the source tree's git HEAD."""
    return Provenance(
        schema_version=SCHEMA_VERSION,
        package_version=_version("actionreasoning"),
        git_revision=git_revision(Path(__file__).resolve().parent.parent),
        pybullet_version=_version("pybullet"),
    )


def _version(distribution: str) -> str | None:
    try:
        return metadata.version(distribution)
    except metadata.PackageNotFoundError:
        return None


def git_revision(package: Path) -> str | None:
    """HEAD of the git checkout whose tracked files include ``package``; None for a copy
    installed elsewhere (even inside another checkout), or where git is missing or fails."""
    try:
        tracked = _git(package, "ls-files", "--error-unmatch", "__init__.py")
        head = _git(package, "rev-parse", "--verify", "HEAD") if tracked is not None else None
    except (OSError, subprocess.SubprocessError):
        return None
    return head


def _git(where: Path, *args: str) -> str | None:
    """What ``git ARGS`` run in ``where`` prints; None if it fails."""
    done = subprocess.run(
        ["git", *args],
        cwd=where,
        capture_output=True,
        text=True,
        timeout=GIT_TIMEOUT_S,
        check=False,
    )
    return done.stdout.strip() if done.returncode == 0 else None
