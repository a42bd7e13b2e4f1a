"""How a model samples its answers: temperature, top-p, token cap, seed and reasoning effort.

The defaults are what every run sent before these settings existed (greedy decoding,
seed 0, answers cut at 300 tokens, no top-p and no reasoning effort), and a setting left at
its default is left out where settings are recorded (run.json, a recording's header), so
runs and recordings made at the defaults stay as they were. Light to import: the command
uses it for its options.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import StrEnum
from typing import Annotated, Any

from pydantic import Field
from pydantic.json_schema import JsonDict

from actionreasoning.errors import ConfigError

#: Answers are a waypoint and a sentence or two; a runaway generation is cut here.
MAX_COMPLETION_TOKENS = 300
MAX_TEMPERATURE = 2.0
MAX_SEED = 2**32 - 1  # llama.cpp's seeds are 32-bit


class Effort(StrEnum):
    """How hard a reasoning model thinks (the OpenAI chat API's ``reasoning_effort``)."""

    LOW = "low"
    MEDIUM = "medium"
    HIGH = "high"


class SamplingError(ConfigError, ValueError):
    """A sampling setting out of range; a ValueError too, so a file holding one is a
    validation error of that file."""


def _unless(default: object) -> Any:
    """Serialized only when not ``default``."""
    return Field(exclude_if=lambda value: value == default)


def _bounds(**bounds: float) -> Any:
    """JSON Schema bounds only: ``__post_init__`` checks them, with the options' messages."""
    extra: JsonDict = {**bounds}
    return Field(json_schema_extra=extra)


#: The command-line option of each setting, for messages.
OPTIONS = {
    "temperature": "--temperature",
    "top_p": "--top-p",
    "max_tokens": "--max-tokens",
    "seed": "--llm-seed",
    "reasoning_effort": "--reasoning-effort",
}


@dataclass(frozen=True)
class Sampling:
    """The sampling settings sent with every request; ``top_p`` and ``reasoning_effort``
    only when set."""

    temperature: Annotated[float, _unless(0.0), _bounds(minimum=0, maximum=MAX_TEMPERATURE)] = 0.0
    top_p: Annotated[
        Annotated[float, _bounds(exclusiveMinimum=0, maximum=1)] | None, _unless(None)
    ] = None
    max_tokens: Annotated[int, _unless(MAX_COMPLETION_TOKENS), _bounds(minimum=1)] = (
        MAX_COMPLETION_TOKENS
    )
    seed: Annotated[int, _unless(0), _bounds(minimum=0, maximum=MAX_SEED)] = 0
    reasoning_effort: Annotated[Effort | None, _unless(None)] = None

    def __post_init__(self) -> None:
        if not 0 <= self.temperature <= MAX_TEMPERATURE:
            raise SamplingError(
                f"--temperature {self.temperature}: give a value from 0 to {MAX_TEMPERATURE:g}"
            )
        if self.top_p is not None and not 0 < self.top_p <= 1:
            raise SamplingError(f"--top-p {self.top_p}: give a value above 0 and at most 1")
        if self.max_tokens < 1:
            raise SamplingError(f"--max-tokens {self.max_tokens}: give at least 1")
        if not 0 <= self.seed <= MAX_SEED:
            raise SamplingError(f"--llm-seed {self.seed}: give a value from 0 to {MAX_SEED}")
        if self.reasoning_effort is not None and self.reasoning_effort not in tuple(Effort):
            raise SamplingError(
                f"--reasoning-effort {self.reasoning_effort}: give one of {', '.join(Effort)}"
            )

    def changed(self) -> dict[str, Any]:
        """The settings that differ from the defaults, by field name."""
        default = Sampling()
        return {
            field.name: getattr(self, field.name)
            for field in fields(self)
            if getattr(self, field.name) != getattr(default, field.name)
        }

    def options(self) -> list[str]:
        """The command-line options of the settings that differ from the defaults."""
        return [OPTIONS[name] for name in self.changed()]

    def __str__(self) -> str:
        values = ((field.name, getattr(self, field.name)) for field in fields(self))
        return ", ".join(f"{name} {value}" for name, value in values if value is not None)


#: A field of settings that is left out of a record when all are at their defaults.
RecordedSampling = Annotated[Sampling, Field(exclude_if=lambda sampling: not sampling.changed())]
