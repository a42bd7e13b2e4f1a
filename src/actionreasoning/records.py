"""Records shared by every layer that reports on a trial: its failure and its LLM cost.

They are written into results.jsonl as they are (DESIGN section 7 fixes the field names).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict


class Failure(BaseModel):
    """Why a trial failed: a short stable ``reason`` code, the agent if any, and details."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    reason: str
    agent: str | None = None
    detail: str


class LLMUsage(BaseModel):
    """LLM cost of a decision or a trial (zeros where no LLM ran); usages add up with ``+``."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_s: float = 0.0

    def __add__(self, other: LLMUsage) -> LLMUsage:
        return LLMUsage(
            calls=self.calls + other.calls,
            prompt_tokens=self.prompt_tokens + other.prompt_tokens,
            completion_tokens=self.completion_tokens + other.completion_tokens,
            latency_s=self.latency_s + other.latency_s,
        )


#: Every failure reason code, with what it means (summaries and reports print it).
FAILURE_CODES: dict[str, str] = {
    "invalid_output": "the model gave no valid answer within its repairs",
    "invalid_choice": "an answer named a brick or target that cannot be used now",
    "collision": "a proposed path would collide or pass too close (σ1, σ6)",
    "descent_blocked": "the way down to the grasp is not clear (σ2)",
    "grasp_failed": "the fingers did not close on the brick with enough force (σ3)",
    "grasp_slip": "the brick slipped or rolled in the hand and the re-grasps ran out (σ4, Ag5)",
    "no_brick_left": "no unused brick can be picked: each left toppled, or fell onto other bricks",
    "placement_misaligned": "the brick could not be set down within tolerance (σ5)",
    "budget_exhausted": "an agent's retries or the single agent's waypoints ran out",
    "unreachable": "a waypoint is out of the arm's reach",
    "tool_error": "a tool was called with arguments that name nothing in the world",
    "safety_limit": "the controller refused a motion outside its safety envelope",
    "step_budget": "the trial spent its simulation steps",
    "time_budget": "the trial spent its wall-clock time",
    "physics_blowup": "the simulation state became non-finite or a brick was flung away",
    "llm_timeout": "the model server did not answer in time",
    "llm_unreachable": "the model server could not be reached",
    "llm_rate_limited": "the model server kept answering 429",
    "llm_server_error": "the model server kept failing (5xx)",
    "llm_bad_response": "the model server sent something that is not a chat completion",
    "llm_bad_request": "the model server refused the request",
    "misplaced": "the build finished but a brick is outside the success limits",
    "not_at_rest": "the build finished but a brick was still moving",
}
