"""Answer errors: the kinds of mistakes a language model makes in this task, as data.

``eval --answer-errors RATE`` corrupts a reasoner's answers with probability RATE
(``reasoners/imperfect.py``), each with one :class:`CorruptionKind`, so that what the gates
catch can be measured offline. :class:`AnswerErrors` is the setting a run records;
:class:`AnswerCorruption` what was done to one answer, kept with its call in the transcript.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.error_kinds import ErrorCategory


class CorruptionKind(StrEnum):
    """A kind of mistake: a stable name (its value), what it changes (``meaning``) and
    which answers it can change (``applies_to``), which the table of docs/agents-and-gates.md
    prints; and the category of refusal it is a mistake of (``expected``), to compare with
    the category its refusal got."""

    meaning: str
    applies_to: str
    expected: ErrorCategory

    def __new__(
        cls, kind: str, meaning: str, applies_to: str, expected: ErrorCategory
    ) -> CorruptionKind:
        member = str.__new__(cls, kind)
        member._value_ = kind
        member.meaning = meaning
        member.applies_to = applies_to
        member.expected = expected
        return member

    SIGN_FLIP = (
        "sign_flip",
        "the sign of the x or y component (drawn among those of 1 mm or more; else z) of the "
        "waypoint's displacement from the tool flipped",
        "a waypoint that moves the tool 1 mm or more",
        ErrorCategory.MISALIGNMENT,
    )
    YAW_90 = (
        "yaw_90",
        "the waypoint's orientation turned by +90 or -90 deg (drawn) about world z",
        "a waypoint",
        ErrorCategory.MISALIGNMENT,
    )
    YAW_180 = (
        "yaw_180",
        "the waypoint's orientation turned by 180 deg about world z",
        "a waypoint",
        ErrorCategory.MISALIGNMENT,
    )
    CM_AS_M = (
        "cm_as_m",
        "the largest component of the waypoint's displacement from the tool times 100 "
        "(centimetres written as metres)",
        "a waypoint that moves the tool 1 mm or more",
        ErrorCategory.FRAME_UNITS,
    )
    INTO_OBSTACLE = (
        "into_obstacle",
        "the waypoint moved to the centre of a placed brick (drawn), or with none placed "
        "lowered to z = 0 (into the ground)",
        "a waypoint",
        ErrorCategory.COLLISION,
    )
    SKIPPED_HOVER = (
        "skipped_hover",
        "a move that should stop above its goal goes down to it: the approach to the brick's "
        "centre height, the carry to the slot's",
        "Ag1's waypoint; the single agent's pre_grasp and transfer waypoints",
        ErrorCategory.PREMATURE_ACTION,
    )
    TOO_FAST = (
        "too_fast",
        "the waypoint's duration_s removed: the move as fast as the controller allows",
        "a waypoint with duration_s",
        ErrorCategory.DYNAMICS,
    )
    WRONG_CHOICE = (
        "wrong_choice",
        "the brick or target replaced (drawn) by a placed brick, a built target or a target "
        "whose support is not built; with none of them, a brick id one past the last",
        "Ag1's answer; the single agent's pre_grasp",
        ErrorCategory.WRONG_CHOICE,
    )
    MISSING_FIELD = (
        "missing_field",
        "one decision field the answer set (drawn) left out: waypoint, gripper_opening_m, "
        "brick_id or target_index None, close False, the single agent's gripper hold",
        "an answer with a decision",
        ErrorCategory.SCHEMA,
    )


class AnswerErrors(BaseModel):
    """How often answers are corrupted (``rate``, 0 to 1) and with which ``kinds``."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    rate: float = Field(0.0, ge=0.0, le=1.0, description="Probability that an answer is corrupted.")
    kinds: tuple[CorruptionKind, ...] = Field(
        tuple(CorruptionKind), min_length=1, description="The kinds drawn from."
    )


class AnswerCorruption(BaseModel):
    """What the imperfect reasoner did to one answer: its kind, one line saying what changed,
    and the answer as the reasoner gave it (JSON)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: CorruptionKind
    detail: str
    original: dict[str, Any]
