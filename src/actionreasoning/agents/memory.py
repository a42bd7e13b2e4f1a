"""Task memory M_t: what has been built, what is being done, and how many retries are left."""

from __future__ import annotations

from enum import StrEnum
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.feedback import Refusal
from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.tools.formulas import roll_rate_deg_s, touch_down_turn_deg
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


class StepDecision(BaseModel):
    """m_i: what an earlier agent decided for the current brick (the decision fields its
    answer set, not its rationale or tool calls), and its verdict."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    agent: Stage
    phase: PlacementPhase | None = None
    brick_id: int | None = None
    target_index: int | None = None
    gripper_opening_m: float | None = None
    close: bool | None = None
    regrasp: bool | None = None
    waypoint: WaypointProposal | None = None
    passed: bool = Field(description="Whether every verdict judged on it passed (sigma_i).")
    failed: tuple[str, ...] = Field(
        (), description="The verdicts that failed on it, which its rung did not enforce."
    )


class RollWatch(BaseModel):
    """Two consecutive measurements of the held brick's roll in the hand (Formulas: roll
    rate), taken over the slot before each set-down: the roll keeps growing as it is carried
    and set down, so the set-down aims for the roll at touch-down."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    before_s: float = Field(description="State time of the first measurement (s).")
    before_deg: float = Field(description="Roll in the hand then (deg).")
    now_s: float = Field(description="State time of the second: the state shown (s).")
    now_deg: float = Field(description="Roll in the hand now (deg).")

    def turn_by_touch_down_deg(self, duration_s: float) -> float:
        """How much further the brick rolls by the touch-down of a set-down taking
        ``duration_s`` a move (Formulas: roll rate)."""
        rate = roll_rate_deg_s(self.before_deg, self.before_s, self.now_deg, self.now_s)
        return touch_down_turn_deg(rate, duration_s)


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
    roll_watch: RollWatch | None = Field(
        None, description="The held brick's roll, measured twice over the slot (set-down)."
    )
    this_brick: tuple[StepDecision, ...] = Field(
        (),
        description="m_1 ... m_(i-1): the decisions accepted in this brick's cycle so far, in "
        "order, each with its verdicts (the state shows where they left the arm).",
    )
