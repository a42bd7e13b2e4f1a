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
