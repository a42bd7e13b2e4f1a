"""Records shared by every layer that reports on a trial: its failure and its LLM cost.

They are written into results.jsonl as they are (DESIGN section 7 fixes the field names).
"""

from __future__ import annotations

from enum import StrEnum
from typing import Self

from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, NonNegativeInt


class Described(StrEnum):
    """A string enum whose members are a short stable code (the value) and what it means
    (``meaning``), which summaries, reports and docs/robustness.md print."""

    meaning: str

    def __new__(cls, code: str, meaning: str) -> Self:
        member = str.__new__(cls, code)
        member._value_ = code
        member.meaning = meaning
        return member


class FailureClass(Described):
    """What ended a failed trial: the reasoning, or the physics after the answers."""

    REASONING = (
        "reasoning",
        "the answers ended it: refused until the budget ran out, a wrong choice, an invalid "
        "or missing output, a move the controller or the safety envelope refused",
    )
    PHYSICS = (
        "physics",
        "the world ended it after answers the checks accepted: a brick slipped, rolled, "
        "toppled, was knocked, or did not come to rest",
    )


class FailureCode(Described):
    """Why a trial failed; :attr:`failure_class` says whether reasoning or physics ended it."""

    INVALID_OUTPUT = "invalid_output", "the model gave no valid answer within its repairs"
    INVALID_CHOICE = "invalid_choice", "an answer named a brick or target that cannot be used now"
    COLLISION = "collision", "a proposed path would collide or pass too close (σ1, σ6)"
    DESCENT_BLOCKED = "descent_blocked", "the way down to the grasp is not clear (σ2)"
    GRASP_FAILED = "grasp_failed", "the fingers did not close on the brick with enough force (σ3)"
    GRASP_SLIP = (
        "grasp_slip",
        "the brick slipped or rolled in the hand and the re-grasps ran out (σ4, Ag5)",
    )
    NO_BRICK_LEFT = (
        "no_brick_left",
        "no unused brick can be picked: each left toppled, or fell onto other bricks",
    )
    PLACEMENT_MISALIGNED = (
        "placement_misaligned",
        "the brick could not be set down within tolerance (σ5)",
    )
    BUDGET_EXHAUSTED = (
        "budget_exhausted",
        "an agent's retries or the single agent's waypoints ran out",
    )
    UNREACHABLE = "unreachable", "a waypoint is out of the arm's reach"
    TOOL_ERROR = "tool_error", "a tool was called with arguments that name nothing in the world"
    SAFETY_LIMIT = "safety_limit", "the controller refused a motion outside its safety envelope"
    STEP_BUDGET = "step_budget", "the trial spent its simulation steps"
    TIME_BUDGET = "time_budget", "the trial spent its wall-clock time"
    PHYSICS_BLOWUP = (
        "physics_blowup",
        "the simulation state became non-finite or a brick was flung away",
    )
    LLM_TIMEOUT = "llm_timeout", "the model server did not answer in time"
    LLM_UNREACHABLE = "llm_unreachable", "the model server could not be reached"
    LLM_RATE_LIMITED = "llm_rate_limited", "the model server kept answering 429"
    LLM_SERVER_ERROR = "llm_server_error", "the model server kept failing (5xx)"
    LLM_BAD_RESPONSE = (
        "llm_bad_response",
        "the model server sent something that is not a chat completion",
    )
    LLM_BAD_REQUEST = "llm_bad_request", "the model server refused the request"
    ABANDONED = (
        "abandoned",
        "the outside agent (Gym environment, MCP client) closed the trial before it ended",
    )
    MISPLACED = "misplaced", "the build finished but a brick is outside the success limits"
    NOT_AT_REST = "not_at_rest", "the build finished but a brick was still moving"

    @property
    def failure_class(self) -> FailureClass:
        """Physics for the codes of something the world did to a brick after accepted
        answers (a slip or roll that used up the re-grasps, a toppled brick, a set-down that
        moved off its checked slot, a brick knocked or still moving at the end, a blow-up);
        reasoning for every other: the answers, or the model that owed them, ended it."""
        return FailureClass.PHYSICS if self in PHYSICS_FAILURES else FailureClass.REASONING


#: The failure codes of physics (:attr:`FailureCode.failure_class`). ``placement_misaligned``
#: is one: every set-down it counts passed the placement plan's forecast against the success
#: rule before it moved, so what sigma_5 measured off is the brick's doing (a roll in the hand
#: on the way down), not the answer's. ``misplaced`` is one: the build ran to its end, every
#: set-down accepted, and a brick was off at the final settle (under a rung that leaves
#: sigma_5 unenforced it may be the answer's: the transcript's unenforced verdicts say so).
PHYSICS_FAILURES = frozenset(
    {
        FailureCode.GRASP_SLIP,
        FailureCode.NO_BRICK_LEFT,
        FailureCode.PLACEMENT_MISALIGNED,
        FailureCode.PHYSICS_BLOWUP,
        FailureCode.MISPLACED,
        FailureCode.NOT_AT_REST,
    }
)


class Failure(BaseModel):
    """Why a trial failed: its code, the agent if any, and details."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    reason: FailureCode
    agent: str | None = None
    detail: str


class LLMUsage(BaseModel):
    """LLM cost of a decision or a trial (zeros where no LLM ran); usages add up with ``+``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    calls: NonNegativeInt = 0
    prompt_tokens: NonNegativeInt = 0
    completion_tokens: NonNegativeInt = 0
    latency_s: NonNegativeFloat = 0.0
    #: The bytes of the pictures the calls sent (their PNGs, once per completion), when the
    #: agents observe the scene in pictures; absent when none were sent.
    image_bytes: NonNegativeInt = Field(0, exclude_if=lambda sent: sent == 0)

    def __add__(self, other: LLMUsage) -> LLMUsage:
        return LLMUsage(
            calls=self.calls + other.calls,
            prompt_tokens=self.prompt_tokens + other.prompt_tokens,
            completion_tokens=self.completion_tokens + other.completion_tokens,
            latency_s=self.latency_s + other.latency_s,
            image_bytes=self.image_bytes + other.image_bytes,
        )
