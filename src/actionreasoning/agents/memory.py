"""Task memory M_t: what has been built, what is being done, and how many retries are left."""

from __future__ import annotations

from enum import StrEnum
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.feedback import Refusal
from actionreasoning.world.stages import Stage


class PlacedBrick(BaseModel):
    """A brick set on its target and released."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    brick_id: int
    target_index: int


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
    steps_done: tuple[Stage, ...] = Field(
        (),
        description="The steps of this brick's cycle whose answers were accepted, in order "
        "(the paper's step completion flags; the state shows where they left the arm).",
    )
