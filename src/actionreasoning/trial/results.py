"""The records of an evaluation run: one :class:`TrialResult` per line of results.jsonl.

The field names are a public interface (DESIGN section 7); ``actionreasoning schema
results`` prints the JSON Schema of a line. Nothing here depends on wall time, so the same
seed gives a byte-identical results.jsonl line, but for the fields of :class:`Provenance`,
which name the code that wrote it.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Collection, Iterable, Mapping, Sequence
from typing import TYPE_CHECKING, Annotated, Any, TypeVar

from pydantic import BaseModel, ConfigDict, Field, NonNegativeFloat, NonNegativeInt, PositiveFloat

from actionreasoning.agents.answer_errors import Caught, CorruptionKind
from actionreasoning.agents.catches import catch_of
from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.agents.tiers import BEFORE_TIERS
from actionreasoning.records import Failure, LLMUsage
from actionreasoning.trial.provenance import Provenance
from actionreasoning.world.geometry import QUAT_NORM_TOLERANCE, Vec3
from actionreasoning.world.scene_spec import Coordinate
from actionreasoning.world.stages import Stage

if TYPE_CHECKING:
    from actionreasoning.agents.transcript import AgentCall

__all__ = [
    "JSON_SCHEMA_DIALECT",
    "AnswerErrorCounts",
    "BrickResult",
    "Failure",
    "FirstAttempts",
    "LLMUsage",
    "PlacementMetrics",
    "Refusals",
    "TrialResult",
    "json_schema",
    "refusals_of",
    "sum_refusals",
]

K = TypeVar("K")
#: Keys of nested counts: names (a kind, a category, a check).
N = TypeVar("N", bound=str)
M = TypeVar("M", bound=str)

#: Refused and failed answers by agent and error category: agent -> category -> count.
Refusals = dict[str, dict[ErrorCategory, NonNegativeInt]]
#: The JSON Schema dialect pydantic's schemas follow, declared by :func:`json_schema`.
JSON_SCHEMA_DIALECT = "https://json-schema.org/draft/2020-12/schema"

#: The bounds of the placement metrics (the paper's Table I), checked on every record.
OffsetCm = Annotated[float, Field(ge=0.0)]
RotationDeg = Annotated[float, Field(ge=0.0, le=180.0)]
IoU = Annotated[float, Field(ge=0.0, le=1.0)]
#: A component of a unit quaternion, normalised within the tolerance the poses are read with.
QuatComponent = Annotated[float, Field(ge=-1.0 - QUAT_NORM_TOLERANCE, le=1.0 + QUAT_NORM_TOLERANCE)]
UnitQuat = tuple[QuatComponent, QuatComponent, QuatComponent, QuatComponent]


def json_schema(model: type[BaseModel]) -> dict[str, Any]:
    """The JSON Schema of ``model`` as written to a file (serialization mode), declaring its
    dialect (``$schema``: draft 2020-12) so that validators check it as such."""
    return {"$schema": JSON_SCHEMA_DIALECT, **model.model_json_schema(mode="serialization")}


class _Record(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class BrickResult(_Record):
    """How one target of the pattern was filled. ``id`` is the brick placed there."""

    id: NonNegativeInt
    size: tuple[PositiveFloat, PositiveFloat, PositiveFloat]
    #: Inside the reach band, whose radii and height are bounded like the workspace's corners.
    target_position: tuple[Coordinate, Coordinate, Coordinate]
    target_orientation: UnitQuat
    #: Where the physics left the brick: the one unbounded number of a line, since no code
    #: keeps a brick a simulation throws within a bound a writer could promise.
    final_position: Vec3
    final_orientation: UnitQuat
    center_offset_cm: OffsetCm
    rotation_error_deg: RotationDeg
    symmetric_rotation_error_deg: RotationDeg
    iou: IoU
    llm_usage: LLMUsage = LLMUsage()


class PlacementMetrics(_Record):
    """The paper's placement metrics of a brick against its target, or their means over a
    trial's bricks."""

    center_offset_cm: OffsetCm
    rotation_error_deg: RotationDeg
    symmetric_rotation_error_deg: RotationDeg
    iou: IoU


class AnswerErrorCounts(_Record):
    """What ``eval --answer-errors`` corrupted, by kind, and what caught the corrupted
    answers (agents/catches.py). Counts add up with ``+``.

    ``caught``: kind -> where each was caught: ``before`` the move, ``after`` it,
    ``missed`` (it ran) or ``trial_stopped`` (the trial ended on it); ``checks``: the
    check (``gate:check``) that caught them, before or after the move -> kind -> count;
    ``led_to``: kind -> what the misses led to (a later check, the trial's failure reason,
    ``misplaced`` or ``harmless``); ``would_catch``: kind -> the check a miss failed that its
    rung did not enforce; ``repeated``: kind -> how many repeated a refused mistake
    (persistence); ``refused_as``: kind -> the error category its refused or failed answers
    got, to compare with the kind's ``expected``. ``caught_by`` is the earlier flat record:
    ``gate:check`` (the first failed check of the last failed verdict on the answer),
    ``refused`` (refused before any gate), ``missed`` or ``trial_stopped``. Each field but
    ``corrupted``, ``by_kind`` and ``caught_by`` is absent when empty (and in lines written
    before it existed)."""

    corrupted: NonNegativeInt = 0
    by_kind: dict[CorruptionKind, NonNegativeInt] = Field(default_factory=dict)
    caught_by: dict[str, NonNegativeInt] = Field(default_factory=dict)
    repeated: dict[CorruptionKind, NonNegativeInt] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    caught: dict[CorruptionKind, dict[Caught, NonNegativeInt]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    checks: dict[str, dict[CorruptionKind, NonNegativeInt]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    led_to: dict[CorruptionKind, dict[str, NonNegativeInt]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    would_catch: dict[CorruptionKind, dict[str, NonNegativeInt]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    refused_as: dict[CorruptionKind, dict[ErrorCategory, NonNegativeInt]] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )

    @classmethod
    def of(
        cls,
        transcript: Sequence[AgentCall],
        failure: Failure | None = None,
        misplaced: Collection[int] = (),
    ) -> AnswerErrorCounts:
        """The corrupted calls of a trial's transcript, counted; ``failure`` is the trial's
        and ``misplaced`` its bricks outside the success rule (what misses led to)."""
        counts = cls()
        for index, call in enumerate(transcript):
            if call.corruption is None:
                continue
            catch = catch_of(transcript, index, failure, misplaced)
            kind = catch.kind
            counts += cls(
                corrupted=1,
                by_kind={kind: 1},
                caught_by={call.caught_by: 1},
                repeated={kind: 1} if catch.repeated else {},
                caught={kind: {catch.caught: 1}},
                checks={} if catch.check is None else {catch.check: {kind: 1}},
                led_to={} if catch.led_to is None else {kind: {catch.led_to: 1}},
                would_catch={} if catch.would_catch is None else {kind: {catch.would_catch: 1}},
                refused_as={} if call.category is None else {kind: {call.category: 1}},
            )
        return counts

    def __add__(self, other: AnswerErrorCounts) -> AnswerErrorCounts:
        kinds = Counter(self.by_kind) + Counter(other.by_kind)
        caught = Counter(self.caught_by) + Counter(other.caught_by)
        repeated = Counter(self.repeated) + Counter(other.repeated)
        return AnswerErrorCounts(
            corrupted=self.corrupted + other.corrupted,
            by_kind={kind: kinds[kind] for kind in CorruptionKind if kind in kinds},
            caught_by=dict(sorted(caught.items())),
            repeated={kind: repeated[kind] for kind in CorruptionKind if kind in repeated},
            caught=_added(self.caught, other.caught, list(CorruptionKind), list(Caught)),
            checks=_added(self.checks, other.checks, None, list(CorruptionKind)),
            led_to=_added(self.led_to, other.led_to, list(CorruptionKind), None),
            would_catch=_added(self.would_catch, other.would_catch, list(CorruptionKind), None),
            refused_as=_added(
                self.refused_as, other.refused_as, list(CorruptionKind), list(ErrorCategory)
            ),
        )


class PerceptionErrors(_Record):
    """An agent's answers that named a brick's pose, with pictures (``--observe image`` or
    ``both``): how many, and how far they were from the bricks as measured, the centre in
    the plane (cm) and the yaw (deg), summed and at most. Errors add up with ``+``."""

    answers: NonNegativeInt = 0
    centre_offset_cm_sum: NonNegativeFloat = 0.0
    centre_offset_cm_max: NonNegativeFloat = 0.0
    yaw_error_deg_sum: NonNegativeFloat = 0.0
    yaw_error_deg_max: NonNegativeFloat = 0.0

    def __add__(self, other: PerceptionErrors) -> PerceptionErrors:
        return PerceptionErrors(
            answers=self.answers + other.answers,
            centre_offset_cm_sum=self.centre_offset_cm_sum + other.centre_offset_cm_sum,
            centre_offset_cm_max=max(self.centre_offset_cm_max, other.centre_offset_cm_max),
            yaw_error_deg_sum=self.yaw_error_deg_sum + other.yaw_error_deg_sum,
            yaw_error_deg_max=max(self.yaw_error_deg_max, other.yaw_error_deg_max),
        )

    @property
    def centre_offset_cm_mean(self) -> float:
        return self.centre_offset_cm_sum / self.answers if self.answers else 0.0

    @property
    def yaw_error_deg_mean(self) -> float:
        return self.yaw_error_deg_sum / self.answers if self.answers else 0.0


class FirstAttempts(_Record):
    """An agent's first answers (calls of attempt 1: one a request, so one a brick, two for
    the placement agent, which also is asked again after a raise): how many it was asked
    for, and how many of them were accepted (or executed) as they came. Counts add up
    with ``+``."""

    asked: NonNegativeInt = 0
    accepted: NonNegativeInt = 0

    def __add__(self, other: FirstAttempts) -> FirstAttempts:
        return FirstAttempts(
            asked=self.asked + other.asked, accepted=self.accepted + other.accepted
        )


def _added(
    one: Mapping[N, Mapping[M, int]],
    two: Mapping[N, Mapping[M, int]],
    keys: Sequence[N] | None,
    inner: Sequence[M] | None,
) -> dict[N, dict[M, int]]:
    """Two nested counts summed: the outer keys in the order of ``keys`` and the inner in
    that of ``inner`` (None: sorted), without zeros."""
    pairs = Counter[tuple[N, M]]()
    for counts in (one, two):
        for key, row in counts.items():
            pairs.update({(key, name): n for name, n in row.items()})
    outer = keys if keys is not None else sorted({key for key, _ in pairs})
    names = inner if inner is not None else sorted({name for _, name in pairs})
    nested = {key: {name: pairs[key, name] for name in names if pairs[key, name]} for key in outer}
    return {key: row for key, row in nested.items() if row}


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
    #: What the agents observed (agents/observation.py); absent when ``state``, as in lines
    #: written before pictures existed.
    observe: str = Field("state", exclude_if=lambda shown: shown == "state")
    #: The rung of verification (agents/verification.py); None in lines written before
    #: rungs existed (agents: full; single agent: none) and for the classical script.
    verify: str | None = None
    #: 0 or more: declared in the JSON Schema; a reader refuses others with its own message
    #: (runs/run_dir.py), naming the line's trial and seed.
    seed: int = Field(json_schema_extra={"minimum": 0})
    trial: int = Field(json_schema_extra={"minimum": 0})
    trial_seed: NonNegativeInt
    success: bool
    llm: str
    bricks: tuple[BrickResult, ...]
    #: The bricks within the success rule's offset and rotation limits of their targets.
    bricks_placed: NonNegativeInt
    metrics: PlacementMetrics
    failure: Failure | None
    llm_usage: LLMUsage = LLMUsage()
    llm_usage_by_agent: dict[str, LLMUsage] = Field(default_factory=dict)
    decisions: NonNegativeInt = 0
    fallback_decisions: NonNegativeInt = 0
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
    #: With pictures: per agent, how far its answers' poses of bricks were from them;
    #: absent without pictures.
    perception: dict[str, PerceptionErrors] = Field(
        default_factory=dict, exclude_if=lambda errors: not errors
    )
    #: Answers nobody corrupted that an enforced pre-move check, sigma_1 or sigma_6 refused,
    #: by ``gate:check`` (agents/catches.py); absent when there were none.
    premove_refusals: dict[str, NonNegativeInt] = Field(
        default_factory=dict, exclude_if=lambda counts: not counts
    )
    sim_steps: NonNegativeInt
