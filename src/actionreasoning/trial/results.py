"""The records of an evaluation run: one :class:`TrialResult` per line of results.jsonl.

The field names are a public interface (DESIGN section 7); ``actionreasoning schema
results`` prints the JSON Schema of a line. Nothing here depends on wall time, so the same
seed gives a byte-identical results.jsonl line, but for the fields of :class:`Provenance`,
which name the code that wrote it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable, Sequence
from typing import TYPE_CHECKING, TypeVar

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.answer_errors import CorruptionKind
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.tiers import BEFORE_TIERS
from actionreasoning.records import Failure, LLMUsage
from actionreasoning.trial.provenance import Provenance
from actionreasoning.world.geometry import QuatXYZW, Vec3
from actionreasoning.world.stages import Stage

if TYPE_CHECKING:
    from actionreasoning.agents.transcript import AgentCall

__all__ = [
    "AnswerErrorCounts",
    "BrickResult",
    "Failure",
    "FirstAttempts",
    "LLMUsage",
    "PlacementMetrics",
    "Refusals",
    "TrialResult",
    "refusals_of",
    "sum_refusals",
]

K = TypeVar("K")

#: Refused and failed answers by agent and error category: agent -> category -> count.
Refusals = dict[str, dict[ErrorCategory, int]]


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
    ``trial_stopped`` (the trial ended on it); and the error category each kind's refused
    or failed answers got (``refused_as``, to compare with the kind's ``expected``; absent
    when none was). Counts add up with ``+``."""

    corrupted: int = 0
    by_kind: dict[CorruptionKind, int] = Field(default_factory=dict)
    caught_by: dict[str, int] = Field(default_factory=dict)
    refused_as: dict[CorruptionKind, dict[ErrorCategory, int]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )

    @classmethod
    def of(cls, transcript: Sequence[AgentCall]) -> AnswerErrorCounts:
        """The corrupted calls of a trial's transcript, counted."""
        return sum(
            (
                cls(
                    corrupted=1,
                    by_kind={call.corruption.kind: 1},
                    caught_by={call.caught_by: 1},
                    refused_as={}
                    if call.category is None
                    else {call.corruption.kind: {call.category: 1}},
                )
                for call in transcript
                if call.corruption is not None
            ),
            cls(),
        )

    def __add__(self, other: AnswerErrorCounts) -> AnswerErrorCounts:
        kinds = Counter(self.by_kind) + Counter(other.by_kind)
        caught = Counter(self.caught_by) + Counter(other.caught_by)
        pairs = Counter[tuple[CorruptionKind, ErrorCategory]]()
        for refused in (self.refused_as, other.refused_as):
            for kind, categories in refused.items():
                pairs.update({(kind, category): n for category, n in categories.items()})
        return AnswerErrorCounts(
            corrupted=self.corrupted + other.corrupted,
            by_kind={kind: kinds[kind] for kind in CorruptionKind if kind in kinds},
            caught_by=dict(sorted(caught.items())),
            refused_as=_nested(pairs, CorruptionKind),
        )


class FirstAttempts(_Record):
    """An agent's first answers (calls of attempt 1: one a request, so one a brick, two for
    the placement agent, which also is asked again after a raise): how many it was asked
    for, and how many of them were accepted (or executed) as they came. Counts add up
    with ``+``."""

    asked: int = 0
    accepted: int = 0

    def __add__(self, other: FirstAttempts) -> FirstAttempts:
        return FirstAttempts(
            asked=self.asked + other.asked, accepted=self.accepted + other.accepted
        )


def sum_refusals(many: Iterable[Refusals]) -> Refusals:
    """Refusals summed (see :func:`_count` for the order)."""
    return _count(
        (agent, category, n)
        for refusals in many
        for agent, categories in refusals.items()
        for category, n in categories.items()
    )


def _count(counts: Iterable[tuple[str, ErrorCategory, int]]) -> Refusals:
    """(agent, category, count) triples summed: the agents in stage order (others, as the
    single agent, after them by name), each agent's categories in their order, no zeros."""
    pairs = Counter[tuple[str, ErrorCategory]]()
    for agent, category, n in counts:
        pairs[agent, category] += n
    return _nested(pairs, sorted({agent for agent, _ in pairs}, key=_stage_order))


def refusals_of(transcript: Sequence[AgentCall]) -> Refusals:
    """Every refused or failed answer of a trial's transcript (repairs included), by agent
    and category."""
    return _count(
        (call.agent, category, 1) for call in transcript for category in call.refused_categories
    )


def _nested(
    pairs: Counter[tuple[K, ErrorCategory]], keys: Iterable[K]
) -> dict[K, dict[ErrorCategory, int]]:
    """``pairs`` as key -> category -> count, in the order of ``keys`` and of the categories,
    without zeros."""
    nested = {key: {c: pairs[key, c] for c in ErrorCategory if pairs[key, c]} for key in keys}
    return {key: counts for key, counts in nested.items() if counts}


def _stage_order(agent: str) -> tuple[int, str]:
    stages = list(Stage)
    return (stages.index(Stage(agent)) if agent in stages else len(stages), agent)


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
    #: The rung of verification (agents/verification.py); None in lines written before
    #: rungs existed (agents: full; single agent: none) and for the classical script.
    verify: str | None = None
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
    #: Refused and failed answers, repairs included, by agent and category; lines of trials
    #: with none (and lines written before categories existed) have no such field.
    refusals: Refusals = Field(default_factory=dict, exclude_if=lambda counts: not counts)
    #: Each agent's answers at attempt 1 of a request and how many were accepted;
    #: absent where no agent was asked (classical) and in lines written before it existed.
    first_attempts: dict[str, FirstAttempts] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    sim_steps: int
