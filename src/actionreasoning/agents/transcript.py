"""Transcripts: every agent call of a trial, with what was measured to judge it.

One :class:`AgentCall` per request to a reasoner: the agent, the brick, the attempt, the
size of the rendered prompt, the answer, the tools it called, the gate verdicts with their
measured values and thresholds, what became of the answer and, if it was refused or failed,
the category of its error (``error_kinds.py``). ``eval --transcripts``
writes them as one JSON line per call. Recording never touches the simulator, so a trial
is the same with and without transcripts.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from pydantic import BaseModel, Field

from actionreasoning.agents.answer_errors import AnswerCorruption
from actionreasoning.agents.error_kinds import ErrorCategory, check_category
from actionreasoning.agents.gates import GateVerdict
from actionreasoning.agents.verification import judged_after_move
from actionreasoning.records import LLMUsage
from actionreasoning.world.pictures import Picture


class Outcome(StrEnum):
    """What became of an answer."""

    PENDING = "pending"  # the trial stopped before the answer was judged
    ACCEPTED = "accepted"
    REFUSED = "refused"  # failed verification or its gate; the agent is asked again
    REGRASP = "regrasp"  # the brick was set aside to be grasped again; the cycle restarts at Ag1
    RAISED = "raised"  # sigma_5 = 0 in contact: raised by delta_h, Ag5 is asked again
    EXECUTED = "executed"  # ran although a check failed that the rung does not enforce
    FAILED = "failed"  # the model gave no valid answer, or its server failed


class CheckRecord(BaseModel):
    """One inequality of a gate with its measured value."""

    name: str
    value: float
    relation: str
    threshold: float
    passed: bool


class GateRecord(BaseModel):
    """A verdict (validation, a pre-move check or a gate sigma_i) and every check behind
    it; whether the run's rung of verification let it refuse the answer (``enforced``), and
    whether it judged a move that had already run (``after_move``)."""

    gate: str
    passed: bool
    checks: list[CheckRecord]
    enforced: bool = True
    after_move: bool = False

    @classmethod
    def of(cls, verdict: GateVerdict, enforced: bool = True) -> GateRecord:
        """The record of a verdict."""
        return cls(
            gate=verdict.gate,
            passed=verdict.passed,
            enforced=enforced,
            after_move=judged_after_move(verdict.gate),
            checks=[
                CheckRecord(
                    name=c.name,
                    value=c.value,
                    relation="<=" if c.at_most else ">=",
                    threshold=c.threshold,
                    passed=c.passed,
                )
                for c in verdict.checks
            ],
        )


class ToolRecord(BaseModel):
    """A tool the reasoner called while answering, with its result."""

    name: str
    arguments: dict[str, Any]
    result: dict[str, Any] | None = None
    error: str | None = None


class PictureRecord(BaseModel):
    """A picture a call carried: which camera and kind (``top_down.depth``), its PNG's size
    and content hash (a recording stores it under that hash)."""

    name: str
    bytes: int
    sha256: str

    @classmethod
    def of(cls, picture: Picture) -> PictureRecord:
        """The record of ``picture``."""
        return cls(name=picture.name, bytes=len(picture.png), sha256=picture.sha256)


class Perceived(BaseModel):
    """How far an answer's pose of a brick (an approach over it, a grasp pose on it) was from
    the brick as measured: its centre in the plane (cm), and its yaw (deg; a brick's yaw is
    defined to a half turn, the grasp's is the brick's)."""

    centre_offset_cm: float
    yaw_error_deg: float


class AgentCall(BaseModel):
    """One request to a reasoner and everything that followed from its answer."""

    call: int = Field(description="Index of the call in the trial, from 0.")
    agent: str
    brick: int | None
    target: int | None
    attempt: int = Field(description="Attempt of this agent on this brick, from 1.")
    prompt_chars: int = Field(
        description="Characters sent to the model for this call, every turn's conversation "
        "counted (the built-in reasoner: the prompt once)."
    )
    pictures: list[PictureRecord] = Field(
        default_factory=list,
        description="The cameras' pictures the call carried (none when agents observe the "
        "state only).",
        exclude_if=lambda pictures: not pictures,
    )
    answer: dict[str, Any]
    tool_calls: list[ToolRecord] = Field(default_factory=list)
    gates: list[GateRecord] = Field(default_factory=list)
    outcome: Outcome = Outcome.PENDING
    feedback: str = Field("", description="Why the answer was refused, as sent back.")
    repairs: list[str] = Field(
        default_factory=list, description="Why the model's earlier outputs were sent back."
    )
    repair_categories: list[ErrorCategory] = Field(
        default_factory=list, description="The category of each of ``repairs``."
    )
    category: ErrorCategory | None = Field(
        None,
        description="The category of the error that refused or failed the answer (None: it "
        "was accepted, executed or not judged).",
    )
    tool_turns: int = 0
    fallback: bool = Field(False, description="Answered by the built-in reasoner instead.")
    usage: LLMUsage = LLMUsage()
    perceived: Perceived | None = Field(
        None,
        description="With pictures: how far the answer's pose of its brick was from it.",
        exclude_if=lambda perceived: perceived is None,
    )
    corruption: AnswerCorruption | None = Field(
        None,
        description="What eval --answer-errors changed in the reasoner's answer (its original "
        "kept there); ``answer`` is the corrupted one, as judged.",
    )

    def conclude(
        self, outcome: Outcome, feedback: str = "", category: ErrorCategory | None = None
    ) -> None:
        """Note what became of the answer and, if it was refused or failed, its category:
        ``category`` if given (an error no gate verdict records), else that of the first
        failed check of its last failed gate verdict. An answer accepted although a verdict
        failed that the rung did not enforce is ``executed``."""
        overruled = any(not gate.passed and not gate.enforced for gate in self.gates)
        if outcome is Outcome.ACCEPTED and overruled:
            outcome = Outcome.EXECUTED
        self.outcome, self.feedback = outcome, feedback
        if outcome in (Outcome.ACCEPTED, Outcome.EXECUTED, Outcome.PENDING):
            self.category = None
            return
        stopped = self._stopped_by()
        check = None if stopped is None else stopped[1]
        self.category = category or (None if check is None else check_category(check))

    @property
    def refused_categories(self) -> list[ErrorCategory]:
        """The category of every refused output of this call, once each: its repairs', then
        its answer's (none of its own when it failed on its repairs: its category is then
        the last repair's)."""
        failed_on_repairs = (
            self.outcome is Outcome.FAILED
            and not self.answer
            and self.category is not ErrorCategory.LLM_FAILURE
        )
        own = [] if self.category is None or failed_on_repairs else [self.category]
        return [*self.repair_categories, *own]

    def _stopped_by(self) -> tuple[str, str | None] | None:
        """The last failed gate verdict and its first failed check (None: no gate failed)."""
        failed = [gate for gate in self.gates if not gate.passed]
        if not failed:
            return None
        return failed[-1].gate, next((c.name for c in failed[-1].checks if not c.passed), None)

    @property
    def caught_by(self) -> str:
        """What stopped this answer: ``gate:check``, the first failed check of its last failed
        gate verdict, when it was refused, raised or re-grasped (else the outcome: a refusal
        before any gate); ``missed`` when it was accepted or executed; ``trial_stopped`` when
        the trial ended on it."""
        if self.outcome in (Outcome.ACCEPTED, Outcome.EXECUTED):
            return "missed"
        if self.outcome in (Outcome.FAILED, Outcome.PENDING):
            return "trial_stopped"
        stopped = self._stopped_by()
        if stopped is None:
            return str(self.outcome)
        gate, check = stopped
        return gate if check is None else f"{gate}:{check}"

    @property
    def brick_in_hand(self) -> int | None:
        """The brick this call was about (for Ag1: the brick it chose)."""
        if self.brick is not None:
            return self.brick
        chosen = self.answer.get("brick_id")
        return chosen if isinstance(chosen, int) else None
