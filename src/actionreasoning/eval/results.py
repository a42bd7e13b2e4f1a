"""The records of an evaluation run: one :class:`TrialResult` per line of results.jsonl.

The field names are a public interface (DESIGN section 7). Nothing here depends on wall
time, so the same seed gives a byte-identical results.jsonl line.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from actionreasoning.world.geometry import QuatXYZW, Vec3


class _Record(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class BrickResult(_Record):
    """How one target of the pattern was filled. ``id`` is the brick placed there."""

    id: int
    size: Vec3
    target_position: Vec3
    target_orientation: QuatXYZW
    final_position: Vec3
    final_orientation: QuatXYZW
    center_offset_cm: float
    rotation_error_deg: float
    symmetric_rotation_error_deg: float
    iou: float


class TrialMetrics(_Record):
    """Means over a trial's bricks."""

    center_offset_cm: float
    rotation_error_deg: float
    symmetric_rotation_error_deg: float
    iou: float


class Failure(_Record):
    """Why a trial failed: a short stable ``reason`` code, the agent if any, and details."""

    reason: str
    agent: str | None = None
    detail: str


class LLMUsage(_Record):
    """LLM cost of a trial (zeros where no LLM ran)."""

    calls: int = 0
    prompt_tokens: int = 0
    completion_tokens: int = 0
    latency_s: float = 0.0


class TrialResult(_Record):
    """One finished trial, as one line of results.jsonl."""

    method: str
    pattern: str
    seed: int
    trial: int
    trial_seed: int
    success: bool
    llm: str
    bricks: tuple[BrickResult, ...]
    bricks_placed: int
    metrics: TrialMetrics
    failure: Failure | None
    llm_usage: LLMUsage = LLMUsage()
    sim_steps: int
