"""What the MCP server's tools return, as models whose JSON Schemas are the tools' output
schemas.

A call's structured result is its tool's reply or a refusal (``{"refusal": {code,
detail}}``, a registry tool's naming the tool), so each output schema is an object that is
one or the other (``anyOf``). A number that is not finite is written as null, as in
results.jsonl, so every number of a schema admits null.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Literal, cast

from pydantic import BaseModel, ConfigDict, Field, create_model
from pydantic.json_schema import (
    GenerateJsonSchema,
    GetJsonSchemaHandler,
    JsonSchemaMode,
    JsonSchemaValue,
    models_json_schema,
)
from pydantic_core import CoreSchema, core_schema

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.agents.view import StateView
from actionreasoning.tools.registry import TOOLS, ToolSchema
from actionreasoning.trial.results import JSON_SCHEMA_DIALECT, TrialResult
from actionreasoning.trial.session import Refusal, ToolReply


@dataclass(frozen=True)
class _SchemaOf:
    """Marks JSON data written from a ``model`` (by the prompt's serializer): its schema is
    the model's."""

    model: type[BaseModel]

    def __get_pydantic_json_schema__(
        self, schema: CoreSchema, handler: GetJsonSchemaHandler
    ) -> JsonSchemaValue:
        return handler(self.model.__pydantic_core_schema__)


class _Reply(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Refused(_Reply):
    """A refused call: nothing was done."""

    refusal: Refusal
    tool: str | None = Field(
        None, exclude_if=lambda tool: tool is None, description="The registry tool refused."
    )


class TrialConditions(_Reply):
    """The trial's conditions as start_trial named them (a pattern file's path normalised);
    ``answer_errors`` only above 0."""

    pattern: str
    physics: str
    noise: str
    tools: str
    observe: str = Field("state", exclude_if=lambda shown: shown == "state")
    seed: int
    trial: int
    answer_errors: float = Field(0.0, exclude_if=lambda rate: rate == 0)


class AgentTurn(_Reply):
    """The waiting agent's turn: its prompt, the state and memory blocks of that prompt as
    JSON, its tools and the gates' measurements with their schemas, the schema of its
    answer and the feedback on its last refused answer."""

    agent: str
    prompt: str
    state: Annotated[dict[str, Any], _SchemaOf(StateView)] = Field(
        description="The state S_t, as the prompt's state block shows it."
    )
    memory: Annotated[dict[str, Any], _SchemaOf(TaskMemory)] = Field(
        description="The memory M_t, as the prompt's memory block shows it."
    )
    tools: list[ToolSchema]
    measurements: list[ToolSchema]
    answer_schema: dict[str, Any]
    feedback: str
    pictures: list[str] = Field(
        default_factory=list,
        description="With observe 'image' or 'both': the pictures the call carries, in the "
        "order of the image content that follows the JSON (top_down.depth: 16-bit PNG, "
        "0.1 mm a count).",
        exclude_if=lambda names: not names,
    )


class StateRead(_Reply):
    """read_state's reply: the trial, the waiting agent's turn (null once the trial has
    ended) and the results line (null while it runs)."""

    trial: TrialConditions
    turn: AgentTurn | None
    result: TrialResult | None


class Started(StateRead):
    """start_trial's reply: read_state's, and the results line of the trial it abandoned."""

    previous_result: TrialResult | None


class Judged(_Reply):
    """submit_answer's reply: the results of the answer's tool calls, or the record of its
    agent call (gates, checks, outcome, feedback); who waits now; the results line once the
    trial has ended."""

    tools: list[ToolReply]
    call: AgentCall | None
    agent: str | None
    result: TrialResult | None


class Finished(_Reply):
    """finish_trial's reply: the trial's results line."""

    result: TrialResult | None


def tool_reply(name: str) -> type[BaseModel]:
    """The reply of registry tool ``name``: its name and its result."""
    tool = TOOLS[name]
    return create_model(
        "".join(part.title() for part in name.split("_")) + "Reply",
        __base__=_Reply,
        __doc__=f"{name}'s result.",
        tool=(cast(Any, Literal[name]), ...),
        result=(tool.output_model, ...),
    )


def output_schema(reply: type[BaseModel]) -> dict[str, Any]:
    """The output schema of a tool whose result is ``reply`` or a refusal."""
    keys: list[tuple[type[BaseModel], JsonSchemaMode]] = [
        (reply, "serialization"),
        (Refused, "serialization"),
    ]
    refs, defs = models_json_schema(keys, schema_generator=_NullableNumbers)
    return {
        "$schema": JSON_SCHEMA_DIALECT,
        "type": "object",
        "anyOf": [refs[key] for key in keys],
        **defs,
    }


class _NullableNumbers(GenerateJsonSchema):
    """Every number may be null: one that is not finite is written so."""

    def float_schema(self, schema: core_schema.FloatSchema) -> JsonSchemaValue:
        return {**super().float_schema(schema), "type": ["number", "null"]}
