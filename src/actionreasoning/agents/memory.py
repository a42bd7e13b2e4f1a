"""Task memory M_t: what has been built, what is being done, and how many retries are left."""

from __future__ import annotations

from enum import StrEnum
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.feedback import Refusal
from actionreasoning.world.geometry import round_floats
from actionreasoning.world.stages import Stage


class PlacedBrick(BaseModel):
    """A brick set on its target and released."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    brick_id: int
    target_index: int


#: Earlier answers are history, shown to millimetres and thousandths.
HISTORY_DIGITS = 3


class EarlierAnswer(BaseModel):
    """An accepted answer of an earlier agent for the current brick: its decision and why."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    agent: str
    decision: dict[str, Any]
    rationale: str

    @classmethod
    def of(cls, agent: str, answer: BaseModel) -> EarlierAnswer:
        """The record of ``agent``'s accepted ``answer`` (its tool calls left out)."""
        decision = answer.model_dump(
            mode="json", exclude={"tool_calls", "rationale"}, exclude_defaults=True
        )
        return cls(
            agent=agent,
            decision=round_floats(decision, HISTORY_DIGITS),
            rationale=getattr(answer, "rationale", ""),
        )


class PlacementPhase(StrEnum):
    """Which of its two calls Ag5 is asked: to carry the brick over its slot, or, over the
    slot and measured there again, to set it down."""

    CARRY = "carry"
    SET_DOWN = "set_down"


class TaskMemory(BaseModel):
    """The orchestrator's memory, shown to every agent."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    placed: tuple[PlacedBrick, ...] = ()
    current_brick: int | None = None
    current_target: int | None = None
    phase: PlacementPhase | None = Field(None, description="Ag5's call, while it is asked.")
    step: Stage | Literal["start", "done"] = Stage.PRE_GRASP
    retries: dict[str, int] = Field(default_factory=dict, description="Attempts used per agent.")
    last_feedback: str = Field("", description="Why the last attempt was refused, if it was.")
    refusals: tuple[Refusal, ...] = Field(
        (),
        description="Every refusal since the current target's brick was first chosen, oldest "
        "first, with what its gate measured: correct the next answer by them.",
    )
    regrasps: int = Field(
        0, description="Times the current target's brick was put down to be grasped again."
    )
    this_brick: tuple[EarlierAnswer, ...] = Field(
        (), description="The accepted answers of this brick's cycle so far, in order."
    )
