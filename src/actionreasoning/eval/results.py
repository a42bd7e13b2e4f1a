"""The records of an evaluation run: one :class:`TrialResult` per line of results.jsonl.

The field names are a public interface (DESIGN section 7); ``actionreasoning schema
results`` prints the JSON Schema of a line. Nothing here depends on wall time, so the same
seed gives a byte-identical results.jsonl line, but for the fields of :class:`Provenance`,
which name the code that wrote it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from typing import TYPE_CHECKING

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.answer_errors import CorruptionKind
from actionreasoning.agents.tiers import BEFORE_TIERS
from actionreasoning.eval.provenance import Provenance
from actionreasoning.records import Failure, LLMUsage
from actionreasoning.world.geometry import QuatXYZW, Vec3

if TYPE_CHECKING:
    from actionreasoning.agents.transcript import AgentCall

__all__ = [
    "AnswerErrorCounts",
    "BrickResult",
    "Failure",
    "LLMUsage",
    "PlacementMetrics",
    "TrialResult",
]


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


class AnswerErrorCounts(_Record):
    """What ``eval --answer-errors`` corrupted, by kind, and what caught the corrupted answers:
    ``gate:check`` (the first failed check of the last failed verdict on the answer),
    ``refused`` (refused before any gate), ``missed`` (accepted or executed) or
    ``trial_stopped`` (the trial ended on it). Counts add up with ``+``."""

    corrupted: int = 0
    by_kind: dict[CorruptionKind, int] = Field(default_factory=dict)
    caught_by: dict[str, int] = Field(default_factory=dict)

    @classmethod
    def of(cls, transcript: Sequence[AgentCall]) -> AnswerErrorCounts:
        """The corrupted calls of a trial's transcript, counted."""
        return sum(
            (
                cls(corrupted=1, by_kind={call.corruption.kind: 1}, caught_by={call.caught_by: 1})
                for call in transcript
                if call.corruption is not None
            ),
            cls(),
        )

    def __add__(self, other: AnswerErrorCounts) -> AnswerErrorCounts:
        kinds = Counter(self.by_kind) + Counter(other.by_kind)
        caught = Counter(self.caught_by) + Counter(other.caught_by)
        return AnswerErrorCounts(
            corrupted=self.corrupted + other.corrupted,
            by_kind={kind: kinds[kind] for kind in CorruptionKind if kind in kinds},
            caught_by=dict(sorted(caught.items())),
        )


class TrialResult(Provenance):
    """One finished trial, as one line of results.jsonl: which code wrote it (empty in
    lines written before that was recorded), then the trial."""

    method: str
    pattern: str
    #: The physics profile and noise level (names; run.json has their values). Lines
    #: written before conditions existed ran under today's "precise" without noise.
    physics: str = "precise"
    noise: str = "none"
    #: The reasoning tier (agents/tiers.py). Lines written before tiers existed ran with
    #: today's "solve" tools.
    tools: str = BEFORE_TIERS
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
    #: With eval --answer-errors RATE > 0 only: lines at rate 0 have no such field.
    answer_errors: AnswerErrorCounts | None = Field(None, exclude_if=lambda counts: counts is None)
    sim_steps: int
