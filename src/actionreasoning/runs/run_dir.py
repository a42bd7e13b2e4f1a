"""An eval output directory: what run it holds (run.json) and its finished trials.

results.jsonl only ever grows by whole lines, each checked to be written whole and synced
as its trial finishes; a write that fails (a full disk) is cut back. A run killed at any
moment leaves at most a partial last line, which resuming cuts off (a whole line that only
lacks its newline is kept); a trial is never written twice, and a line whose trial index
does not fit its seed is refused. run.json records what makes trials comparable (the
method, the pattern and its hash, the seed, and every value of the trial configuration
with its hash), so a different configuration cannot be mixed into the same directory.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import json
import os
from pathlib import Path
from typing import IO, Any

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.observation import DEFAULT_OBSERVATION
from actionreasoning.agents.tiers import BEFORE_TIERS
from actionreasoning.errors import ConfigError, StorageError
from actionreasoning.runs.layout import RunDir
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.rules import Method, rung_of, trial_seed
from actionreasoning.world.config_files import one_line, open_user_file, read_user_file
from actionreasoning.world.models import Supply


class RunManifest(BaseModel):
    """What every trial of a run shares: run.json. Trial count, workers and outputs may
    differ. ``config`` is the trial configuration, ``config_sha256`` the hash of all its
    recorded values (:func:`config_digest`); read back, its backend holds only what is
    recorded of one (``trial_config.Backend``), the rest at its defaults."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: str
    pattern: str
    pattern_sha256: str
    #: Where the pattern's bricks wait (absent from run.json written before supplies).
    supply: Supply = Supply.SCATTERED
    seed: int
    config: TrialConfig
    config_sha256: str

    @classmethod
    def sealed(
        cls,
        method: str,
        pattern: str,
        pattern_sha256: str,
        seed: int,
        config: TrialConfig,
        supply: Supply = Supply.SCATTERED,
    ) -> RunManifest:
        """A manifest with ``config``'s hash."""
        return cls(
            method=method,
            pattern=pattern,
            pattern_sha256=pattern_sha256,
            supply=supply,
            seed=seed,
            config=config,
            config_sha256=config_digest(config),
        )

    @model_validator(mode="after")
    def _hash_matches(self) -> RunManifest:
        if config_digest(self.config) != self.config_sha256:
            raise ValueError("config_sha256 is not the hash of config: the file was edited")
        return self

    @property
    def llm(self) -> str:
        """The reasoning backend as given (``openai:MODEL``), or ``none`` (classical)."""
        return "none" if self.config.llm is None else self.config.llm.spec

    @property
    def physics_name(self) -> str:
        return self.config.physics.name

    @property
    def noise_name(self) -> str:
        return self.config.noise.name

    @property
    def answer_errors(self) -> AnswerErrors:
        return self.config.answer_errors

    @property
    def tier(self) -> str:
        """The reasoning tier its agents ran in."""
        return str(self.config.tools)

    @property
    def observation(self) -> str:
        """What its agents observed of the scene."""
        return str(self.config.observe)

    def fields(self) -> dict[str, Any]:
        """Every recorded value, nested ones dotted and those of the config by their path
        in it (``tolerances.c_min_m``); the hash, which only sums them up, left out."""
        plain = self.model_dump(mode="json", exclude={"config", "config_sha256"})
        return _flatten({**plain, **self.config.model_dump(mode="json")})


class EarlierManifest(BaseModel):
    """run.json as written before the trial configuration was recorded (results lines of
    schema version 1): read by `report`, never resumed. Its :meth:`fields` are named as
    today's are."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: str
    pattern: str
    pattern_sha256: str
    seed: int
    llm: str
    llm_limits: dict[str, int | bool]
    success_rule: str
    budget: dict[str, float]
    physics: dict[str, Any]
    noise: dict[str, Any]

    @property
    def physics_name(self) -> str:
        return str(self.physics["name"])

    @property
    def noise_name(self) -> str:
        return str(self.noise["name"])

    @property
    def answer_errors(self) -> AnswerErrors:
        """Rate 0: answer errors did not exist yet."""
        return AnswerErrors()

    @property
    def tier(self) -> str:
        """Tiers did not exist yet: the agents had today's solve tools."""
        return BEFORE_TIERS

    @property
    def observation(self) -> str:
        """Pictures did not exist yet: the agents observed the state."""
        return str(DEFAULT_OBSERVATION)

    def fields(self) -> dict[str, Any]:
        """What it recorded, by the names a :class:`RunManifest` gives the same values."""
        limits = {k: v for k, v in self.llm_limits.items() if k != "fallback"}
        backend = {"spec": self.llm, "limits": limits, "fallback": self.llm_limits.get("fallback")}
        plain = self.model_dump(include={"method", "pattern", "pattern_sha256", "seed"})
        config = {
            "physics": self.physics,
            "noise": self.noise,
            "budget": self.budget,
            "success_rule": self.success_rule,
            "llm": None if self.llm == "none" else backend,
        }
        return _flatten({**plain, **config})


class RecordedManifest(BaseModel):
    """run.json of an earlier version whose trial configuration this version reads no more
    (a threshold renamed or added since, say): read by `report` as it was recorded, never
    resumed."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    method: str
    pattern: str
    pattern_sha256: str
    supply: Supply = Supply.SCATTERED
    seed: int
    config: dict[str, Any]
    config_sha256: str

    @model_validator(mode="after")
    def _hash_matches(self) -> RecordedManifest:
        if values_digest(self.config) != self.config_sha256:
            raise ValueError("config_sha256 is not the hash of config: the file was edited")
        return self

    @property
    def llm(self) -> str:
        backend = self.config.get("llm")
        return "none" if backend is None else str(backend["spec"])

    @property
    def physics_name(self) -> str:
        return str(self.config["physics"]["name"])

    @property
    def noise_name(self) -> str:
        return str(self.config["noise"]["name"])

    @property
    def answer_errors(self) -> AnswerErrors:
        return AnswerErrors.model_validate(self.config.get("answer_errors", {}))

    @property
    def tier(self) -> str:
        """The reasoning tier; solve where it was recorded before tiers existed."""
        return str(self.config.get("tools", BEFORE_TIERS))

    @property
    def observation(self) -> str:
        """What the agents observed; the state where none is recorded."""
        return str(self.config.get("observe", DEFAULT_OBSERVATION))

    def fields(self) -> dict[str, Any]:
        """Every recorded value, named as a :class:`RunManifest` names them."""
        plain = self.model_dump(mode="json", exclude={"config", "config_sha256"})
        return _flatten({**plain, **self.config})


#: run.json of this version, of one whose configuration this version reads no more, or of
#: one before the trial configuration was recorded.
AnyManifest = RunManifest | RecordedManifest | EarlierManifest


def config_digest(config: TrialConfig) -> str:
    """SHA-256 of a configuration's recorded values (see :func:`values_digest`)."""
    return values_digest(config.model_dump(mode="json"))


def values_digest(values: dict[str, Any]) -> str:
    """SHA-256 of recorded values as compact JSON with sorted keys."""
    return digest(json.dumps(values, sort_keys=True, separators=(",", ":")))


def _flatten(data: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    flat: dict[str, Any] = {}
    for name, value in data.items():
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{prefix}{name}."))
        else:
            flat[f"{prefix}{name}"] = value
    return flat


def digest(text: str) -> str:
    """SHA-256 of a text, hex."""
    return hashlib.sha256(text.encode()).hexdigest()


def check_output_path(out: Path) -> None:
    """Refuse ``out`` if it exists and is no directory; create nothing."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")


def output_directory(out: Path) -> None:
    """Create ``out`` if new; a path that is no directory, or cannot be made one, is refused."""
    check_output_path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise ConfigError(
            f"--out {out}: cannot create that directory ({error.strerror})"
        ) from error


def open_run(out: Path, manifest: RunManifest) -> list[TrialResult]:
    """Create ``out`` for this run, or check it holds the same run; its finished trials."""
    output_directory(out)
    results, stored = RunDir(out).results, RunDir(out).manifest
    if results.exists() and not results.is_file():  # e.g. a FIFO: appending would block
        read_user_file(results, "results file", limit=None)
    if not results.exists() or results.stat().st_size == 0:
        temporary = stored.with_suffix(".tmp")
        try:
            temporary.write_text(manifest.model_dump_json(indent=2) + "\n")
            os.replace(temporary, stored)
        except OSError as error:  # a full disk: no half-written run.json is left
            temporary.unlink(missing_ok=True)
            raise write_error(stored, error, "no trial has run yet") from error
        return []
    if not stored.exists():
        raise ConfigError(
            f"{results} exists but {stored} does not: not a run this version can resume; "
            "choose another --out"
        )
    try:
        previous = read_manifest(stored)
    except ConfigError as error:
        raise ConfigError(f"{error}: choose another --out") from error
    differences = _differences(previous.fields(), manifest.fields())
    if differences:
        raise ConfigError(
            f"--out {out} holds a different run ({', '.join(differences)}): choose another "
            "--out, or repeat that run's options, under the settings it ran with, to resume it"
        )
    finished = read_results(results, repair=True)
    check_lines(finished, manifest, results, stored)
    return finished


def check_lines(
    results: list[TrialResult], manifest: AnyManifest, path: Path, stored: Path
) -> None:
    """Refuse, in one line naming the line and the field, a results line (of ``path``) that
    differs from run.json (``stored``) in anything run.json fixes that a line records:
    method, pattern, seed, backend, physics, noise, tier, observation and rung of
    verification. `report`
    and a resume share it, so that no trial of another condition is pooled. (A line records
    what answer errors did, not their rate, so it is not checked against the rate.)"""
    expected: dict[str, Any] = {
        "method": manifest.method,
        "pattern": manifest.pattern,
        "seed": manifest.seed,
        "llm": manifest.llm,
        "physics": manifest.physics_name,
        "noise": manifest.noise_name,
        "tools": manifest.tier,
        "observe": manifest.observation,
    }
    if isinstance(manifest, RunManifest):
        rung = rung_of(Method(manifest.method), manifest.config.verify)
        expected["verify"] = None if rung is None else str(rung)
    for number, result in enumerate(results, start=1):
        found_values = {name: getattr(result, name) for name in expected}
        if result.verify is None and result.method == manifest.method != Method.CLASSICAL:
            # Lines written before rungs existed ran under the method's own (a line of
            # another method is refused for its method first).
            found_values["verify"] = str(rung_of(Method(result.method), None))
        for name, value in expected.items():
            found = found_values[name]
            if found != value:
                raise ConfigError(
                    f"{path} line {number} is a trial of {name} {found!r}, but {stored} says "
                    f"{value!r}: lines of another run were written into this directory"
                )


def read_manifest(path: Path) -> RunManifest:
    """The run.json at ``path`` to resume; a damaged one, or one of another version, is an
    error."""
    manifest = read_any_manifest(path)
    if isinstance(manifest, EarlierManifest):
        raise ConfigError(
            f"{path} was written by an earlier version of actionreasoning, which did not "
            "record the trial configuration, so a resume cannot be checked against it"
        )
    if isinstance(manifest, RecordedManifest):
        raise ConfigError(
            f"{path} was written by an earlier version of actionreasoning, whose trial "
            "configuration this version reads no more, so it cannot be resumed (`report` "
            "still reads it)"
        )
    return manifest


def read_any_manifest(path: Path) -> AnyManifest:
    """The run.json at ``path``, also one written before the trial configuration was
    recorded (for a report: such a run cannot be resumed); a damaged one is an error."""
    data = read_user_file(path, "run file")
    try:
        return RunManifest.model_validate_json(data)
    except ValidationError as error:
        with contextlib.suppress(ValidationError):
            return RecordedManifest.model_validate_json(data)
        with contextlib.suppress(ValidationError):
            return EarlierManifest.model_validate_json(data)
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"])
        raise ConfigError(
            f"{path} is damaged or from an earlier version ({where}: {first['msg']})"
        ) from error


def _differences(there: dict[str, Any], now: dict[str, Any]) -> list[str]:
    """Every field (flattened: ``physics.time_step_s``) that differs, with both values."""
    found = []
    for name in dict.fromkeys([*there, *now]):
        old, new = there.get(name), now.get(name)
        if old != new:
            found.append(f"{name} {old!r} there, {new!r} now")
    return found


#: The longest line a results file may hold. A trial's line takes some 700 bytes a brick,
#: so even the largest pattern a pattern file can hold (1 MiB of bricks) fits; a longer
#: line is no trial result, and is refused without being read whole.
MAX_LINE_BYTES = 64 << 20
_PIECE_BYTES = 1 << 20


def read_results(path: Path, repair: bool = False) -> list[TrialResult]:
    """The trials in a results.jsonl, every line checked. A last line cut short is ignored
    and a whole one that only lacks its newline kept; ``repair`` mends the file to match.

    The file is read line by line: memory holds the trials and one line, never the file. A
    line longer than :data:`MAX_LINE_BYTES` is refused with its number, and a file whose
    first line holds NUL bytes is not a results file.
    """
    results: list[TrialResult] = []
    seen: set[int] = set()
    mend: tuple[int, bytes] | None = None  # cut the file at this offset and add these bytes
    with open_user_file(path, "results file") as handle:
        number = offset = 0
        while chunk := _next_line(path, handle, number + 1):
            if not chunk.endswith(b"\n"):
                if _cut_short(chunk):
                    mend = (offset, b"")
                    break
                mend = (offset + len(chunk), b"\n")
            for line in chunk.splitlines():
                number += 1
                results.append(_result(path, number, line, seen))
            offset += len(chunk)
    if repair and mend is not None:
        try:
            _mend(path, *mend)
        except OSError as error:
            raise write_error(path, error, "its whole lines are kept") from error
    return results


def _next_line(path: Path, handle: IO[bytes], number: int) -> bytes:
    """Line ``number`` of the results file, its newline included (empty at the end), read
    in pieces: one longer than :data:`MAX_LINE_BYTES` is refused once that much is read,
    and a first line holding NUL bytes at its first piece."""
    pieces: list[bytes] = []
    size = 0
    try:
        while piece := handle.readline(_PIECE_BYTES):
            if number == 1 and b"\0" in piece:
                raise ConfigError(
                    f"{path} is not a results file (it holds NUL bytes where its first line "
                    "should be)"
                )
            pieces.append(piece)
            size += len(piece)
            ended = piece.endswith(b"\n")
            if size - ended > MAX_LINE_BYTES:
                raise ConfigError(
                    f"{path} line {number} is longer than {MAX_LINE_BYTES >> 20} MiB: not a "
                    "trial result"
                )
            if ended:
                break
    except OSError as error:
        raise ConfigError(
            f"{path}: cannot read results file ({one_line(error.strerror or error)})"
        ) from error
    return b"".join(pieces)


def _result(path: Path, number: int, line: bytes, seen: set[int]) -> TrialResult:
    """Line ``number``'s trial, checked; its index is added to ``seen``."""
    try:
        result = TrialResult.model_validate_json(line)
    except ValidationError as error:
        raise ConfigError(
            f"{path} line {number} is not a trial result ({error.errors()[0]['msg']})"
        ) from error
    _check_index(result, f"{path} line {number}")
    if result.trial in seen:
        raise ConfigError(f"{path} line {number} repeats trial {result.trial}")
    seen.add(result.trial)
    return result


def _mend(path: Path, kept: int, added: bytes) -> None:
    """Cut the file to its first ``kept`` bytes and append ``added``."""
    with path.open("r+b") as handle:
        handle.truncate(kept)
        handle.seek(kept)
        handle.write(added)
        os.fsync(handle.fileno())


def _cut_short(last: bytes) -> bool:
    """Whether a last line without its newline was cut short (not JSON): any JSON is a
    whole line that only lacks its newline, checked as a result after."""
    try:
        TrialResult.model_validate_json(last)
    except ValidationError as error:
        return error.errors()[0]["type"] == "json_invalid"
    return False


def _check_index(result: TrialResult, where: str) -> None:
    """Refuse a trial index that cannot be (negative) or is not its seed's (edited)."""
    if result.trial < 0 or result.seed < 0:
        raise ConfigError(
            f"{where}: trial {result.trial} of seed {result.seed} is not a trial "
            "(indices and seeds are 0 or more)"
        )
    expected = trial_seed(result.seed, result.trial)
    if result.trial_seed != expected:
        raise ConfigError(
            f"{where}: trial {result.trial} of seed {result.seed} has trial_seed "
            f"{result.trial_seed}, not {expected}: the line was edited or damaged"
        )


def append_result(sink: IO[bytes], result: TrialResult) -> None:
    """Append one result line, check that all of it was written and push it to the disk.

    ``sink`` is the results file opened unbuffered for appending (``open(path, "ab", 0)``).
    If writing or syncing fails (a full disk), the file is cut back to its whole lines and
    the error raised. An interrupt (Ctrl-C) cuts back only a line not yet written whole: a
    whole line is a finished trial, kept.
    """
    line = (result.model_dump_json() + "\n").encode()
    start = os.fstat(sink.fileno()).st_size
    written = 0
    try:
        while written < len(line):  # one call, unless the disk takes only part of the line
            count = sink.write(line[written:])
            if not count:
                raise OSError(errno.EIO, "the line was not written")
            written += count
        os.fsync(sink.fileno())
    except BaseException as error:
        if isinstance(error, OSError) or written < len(line):
            with contextlib.suppress(OSError):
                os.ftruncate(sink.fileno(), start)
        raise


def write_file(path: Path, data: bytes, kept: str) -> None:
    """Write ``path`` (making its folders) whole or not at all: under its
    :func:`partial_name` first, renamed to ``path`` once all is written and closed. A failure
    deletes the partial file and raises :func:`write_error`'s error."""
    partial = partial_name(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial.write_bytes(data)
        os.replace(partial, path)
    except OSError as error:
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)
        raise write_error(path, error, kept) from error


def partial_name(path: Path) -> Path:
    """Where ``path`` is written before it is whole (``trial_000.rrd.partial``): a name no
    reader looks for, nor matches by its extension."""
    return path.with_name(f"{path.name}.partial")


def write_error(path: Path, error: OSError, kept: str) -> StorageError:
    """One line for a write that failed: the file, the system's reason, the disk it is on,
    and ``kept``, what is safe."""
    return StorageError(
        f"cannot write {path}: {error.strerror or error} (the disk mounted at "
        f"{_mount_point(path)}); {kept}; make room, then run the same command again"
    )


def _mount_point(path: Path) -> Path:
    """The mount point of the file system that holds (or would hold) ``path``."""
    place = Path(os.path.abspath(path)).parent
    while not os.path.ismount(place):
        place = place.parent
    return place
