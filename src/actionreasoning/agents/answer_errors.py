"""Answer errors: the kinds of mistakes a language model makes in this task, as data.

``eval --answer-errors RATE`` corrupts a reasoner's answers with probability RATE
(``reasoners/imperfect.py``), each with one :class:`CorruptionKind`, so that what the gates
catch can be measured offline. :class:`AnswerErrors` is the setting a run records;
:class:`AnswerCorruption` what was done to one answer, kept with its call in the transcript.
:data:`GUARDING_TOLERANCES` says which tolerance guards each step's waypoint: a near-miss is
off by one to three of it.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import StrEnum
from typing import Any, Final

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.errors import ConfigError


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
        "centre height",
        "Ag1's waypoint; the single agent's pre_grasp",
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
        "brick_id or target_index None, close False",
        "an answer with a decision",
        ErrorCategory.SCHEMA,
    )
    NEAR_OFFSET = (
        "near_offset",
        "the waypoint's position shifted horizontally in a drawn direction by k times the "
        "position tolerance that guards it (k drawn from 1 to 3)",
        "a waypoint of a stage a tolerance guards it at (GUARDING_TOLERANCES)",
        ErrorCategory.MISALIGNMENT,
    )
    NEAR_YAW = (
        "near_yaw",
        "the waypoint's orientation turned about world z by +k or -k (drawn) times the yaw "
        "tolerance that guards it (k drawn from 1 to 3)",
        "a waypoint of a stage a tolerance guards it at (GUARDING_TOLERANCES)",
        ErrorCategory.MISALIGNMENT,
    )


#: ``--answer-error-kinds``'s word for every kind.
ALL_KINDS = "all"


def parse_kinds(text: str) -> tuple[CorruptionKind, ...]:
    """The kinds named in ``text`` (comma-separated names, or ``all``), once each, in the
    order of :class:`CorruptionKind` (so that a run is the same whatever order names them);
    an unknown or missing name is a :class:`ConfigError` naming it."""
    names = [name.strip() for name in text.split(",")]
    if names == [ALL_KINDS]:
        return tuple(CorruptionKind)
    known = {kind.value: kind for kind in CorruptionKind}
    for name in names:
        if name not in known:
            what = f"unknown kind {name[:40]!r}" if name else "an empty kind name"
            raise ConfigError(
                f"--answer-error-kinds {text[:80]!r}: {what} (kinds: {ALL_KINDS}, "
                f"{', '.join(known)})"
            )
    return tuple(kind for kind in CorruptionKind if kind.value in names)


#: The near-misses: off by NEAR_MISS_FACTORS (low, high) times a guarding tolerance.
NEAR_MISSES: Final = frozenset({CorruptionKind.NEAR_OFFSET, CorruptionKind.NEAR_YAW})
#: A near-miss is off by k times its tolerance, k drawn uniformly from this range.
NEAR_MISS_FACTORS: Final = (1.0, 3.0)
#: The tolerances (``Tolerances`` fields) that guard each step's waypoint, its position and
#: its yaw, read from the request's tolerances (the run's, widened under noise): what a
#: near-miss is measured in. Keys are the agents' stages (the single agent's steps); None
#: where no tolerance guards it. The approach's position is free over the brick (the
#: descent goes to the brick's centre) and the return's pose wherever its way is clear; a
#: grasp's offset along the brick is sigma_3's, a lift's sideways travel is judged by the
#: drag it makes while the brick touches its support, a slot by sigma_5's seat.
GUARDING_TOLERANCES: Final[Mapping[str, tuple[str | None, str | None]]] = {
    "pre_grasp": (None, "eps_g_deg"),
    "descent": ("eps_g_m", "eps_g_deg"),
    "grasp": ("eps_g_m", "eps_g_deg"),
    "lift": ("lift_drag_m", "lift_drag_deg"),
    "placement": ("eps_xy_m", "eps_theta_deg"),
    "release": (None, None),
}


class Caught(StrEnum):
    """Where a corrupted answer was caught, if it was."""

    BEFORE = "before"  # refused by an enforced verdict judged before the arm moved
    AFTER = "after"  # refused, raised or put down by an enforced gate judged after the move
    MISSED = "missed"  # it ran: accepted, or executed past a check the rung does not enforce
    TRIAL_STOPPED = "trial_stopped"  # the trial ended on it (it failed, or was not judged)


class AnswerErrors(BaseModel):
    """How often answers are corrupted (``rate``, 0 to 1), with which ``kinds``, and how
    often the answer after a refused corrupted one repeats its mistake (``persistence``, 0
    to 1; not recorded at 0, so run.json is as it was without it)."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    rate: float = Field(0.0, ge=0.0, le=1.0, description="Probability that an answer is corrupted.")
    kinds: tuple[CorruptionKind, ...] = Field(
        tuple(CorruptionKind), min_length=1, description="The kinds drawn from."
    )
    persistence: float = Field(
        0.0,
        ge=0.0,
        le=1.0,
        exclude_if=lambda persistence: persistence == 0.0,
        description="Probability that the answer after a refusal of a corrupted answer "
        "repeats its mistake (the same kind, on the same field).",
    )


class AnswerCorruption(BaseModel):
    """What the imperfect reasoner did to one answer: its kind, one line saying what changed,
    the answer as the reasoner gave it (JSON), and whether it repeats the mistake of the
    refused answer before it (``repeated``, absent when not)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: CorruptionKind
    detail: str
    original: dict[str, Any]
    repeated: bool = Field(False, exclude_if=lambda repeated: not repeated)
