"""The records of an evaluation run: one :class:`TrialResult` per line of results.jsonl.

The field names are a public interface (DESIGN section 7); ``actionreasoning schema
results`` prints the JSON Schema of a line. Nothing here depends on wall time, so the same
seed gives a byte-identical results.jsonl line, but for the fields of :class:`Provenance`,
which name the code that wrote it.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.eval.provenance import Provenance
from actionreasoning.records import Failure, LLMUsage
from actionreasoning.world.geometry import QuatXYZW, Vec3

__all__ = ["BrickResult", "Failure", "LLMUsage", "PlacementMetrics", "TrialResult"]


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
    llm_usage: LLMUsage = LLMUsage()


class PlacementMetrics(_Record):
    """The paper's placement metrics of a brick against its target, or their means over a
    trial's bricks."""

    center_offset_cm: float
    rotation_error_deg: float
    symmetric_rotation_error_deg: float
    iou: float


class TrialResult(Provenance):
    """One finished trial, as one line of results.jsonl: which code wrote it (empty in
    lines written before that was recorded), then the trial."""

    method: str
    pattern: str
    #: The physics profile and noise level (names; run.json has their values). Lines
    #: written before conditions existed ran under today's "precise" without noise.
    physics: str = "precise"
    noise: str = "none"
    seed: int
    trial: int
    trial_seed: int
    success: bool
    llm: str
    bricks: tuple[BrickResult, ...]
    bricks_placed: int
    metrics: PlacementMetrics
    failure: Failure | None
    llm_usage: LLMUsage = LLMUsage()
    llm_usage_by_agent: dict[str, LLMUsage] = Field(default_factory=dict)
    decisions: int = 0
    fallback_decisions: int = 0
    sim_steps: int
