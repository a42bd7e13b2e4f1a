"""Task memory M_t: what has been built, what is being done, and how many retries are left."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class PlacedBrick(BaseModel):
    """A brick set on its target and released."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    brick_id: int
    target_index: int


class TaskMemory(BaseModel):
    """The orchestrator's memory, shown to every agent."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    placed: tuple[PlacedBrick, ...] = ()
    current_brick: int | None = None
    current_target: int | None = None
    step: str = "pre_grasp"
    retries: dict[str, int] = Field(default_factory=dict, description="Attempts used per agent.")
    flags: dict[str, bool] = Field(default_factory=dict, description="Gates passed this brick.")
    last_feedback: str = Field("", description="Why the last attempt was refused, if it was.")
    regrasps: int = Field(
        0, description="Times the current target's brick was put down to be grasped again."
    )
