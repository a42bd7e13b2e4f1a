"""Error categories: every refused or failed answer by kind, as the Embodied Agent Interface
reports errors.

An answer is refused by validation (``validation.py``: its :class:`OutputError` carries the
category), by a check of a gate or of a pre-move plan (:data:`CHECK_CATEGORIES`: the check's
name says which), or fails with no answer at all (``llm_failure``). The categories are the
kinds of :class:`~actionreasoning.agents.answer_errors.CorruptionKind` (its ``expected``), so
that a corrupted answer's kind and the category of its refusal can be compared.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Final

from actionreasoning.records import Described


class ErrorCategory(Described):
    """A kind of refused or failed answer: a stable name (its value) and what it covers."""

    SCHEMA = (
        "schema",
        "not JSON, not the agent's schema, or a decision field left out",
    )
    HALLUCINATED_ID = (
        "hallucinated_id",
        "a brick id, target index or tool name that names nothing",
    )
    WRONG_CHOICE = "wrong_choice", "an existing brick or target that cannot be chosen now"
    FRAME_UNITS = (
        "frame_units",
        "a pose outside the workspace box or a quaternion that is not unit: numbers in the "
        "wrong frame or units",
    )
    MISALIGNMENT = "misalignment", "a pose off its goal: offset, turned or tilted"
    COLLISION = "collision", "a path or pose with too little clearance, or into contact"
    UNREACHABLE = "unreachable", "a pose the arm cannot reach"
    PREMATURE_ACTION = (
        "premature_action",
        "a gripper action or a move before its stage allows it: too narrow an opening, no "
        "close at the grasp, a move down to its goal without stopping above it",
    )
    DYNAMICS = "dynamics", "a move too fast, or a brick slipping in the hand"
    GRASP = "grasp", "fingers that do not hold the brick (or hold it rolled)"
    LLM_FAILURE = (
        "llm_failure",
        "no answer at all: the model's server failed or timed out",
    )


_C = ErrorCategory

#: Every check a gate or a pre-move check can fail (gates.py, orchestrator.py), by name,
#: with the category of the answer it refuses. ``valid_answer`` is refused by validation:
#: its answer takes the category of the OutputError, this one where none is known.
CHECK_CATEGORIES: Final[Mapping[str, ErrorCategory]] = MappingProxyType(
    {
        "valid_answer": _C.SCHEMA,
        "answer_complete": _C.SCHEMA,
        "target_buildable": _C.WRONG_CHOICE,
        "brick_free": _C.WRONG_CHOICE,
        "brick_under_approach": _C.HALLUCINATED_ID,
        "brick_fits_target": _C.WRONG_CHOICE,
        "grip_offset_m": _C.MISALIGNMENT,
        "grip_yaw_deg": _C.MISALIGNMENT,
        "pointing_down_deg": _C.MISALIGNMENT,
        "pose_error_m": _C.MISALIGNMENT,
        "pose_error_deg": _C.MISALIGNMENT,
        "drag_m": _C.MISALIGNMENT,
        "drag_turn_deg": _C.MISALIGNMENT,
        "predicted_offset_m": _C.MISALIGNMENT,
        "predicted_rotation_deg": _C.MISALIGNMENT,
        "d_perp_m": _C.MISALIGNMENT,
        "e_xy_m": _C.MISALIGNMENT,
        "e_theta_deg": _C.MISALIGNMENT,
        "tilt_deg": _C.MISALIGNMENT,
        "offset_m": _C.MISALIGNMENT,
        "rotation_deg": _C.MISALIGNMENT,
        "clearance_m": _C.COLLISION,
        "hover_clearance_m": _C.COLLISION,
        "pad_room_m": _C.COLLISION,
        "way_clearance_m": _C.COLLISION,
        "retreat_clearance_m": _C.COLLISION,
        "return_clearance_m": _C.COLLISION,
        "set_down_clearance_m": _C.COLLISION,
        "bottom_clearance_m": _C.COLLISION,
        "sidewall_force_n": _C.COLLISION,
        "brick_shift_m": _C.COLLISION,
        "reachable": _C.UNREACHABLE,
        "way_reachable": _C.UNREACHABLE,
        "retreat_reachable": _C.UNREACHABLE,
        "return_reachable": _C.UNREACHABLE,
        "set_down_reachable": _C.UNREACHABLE,
        "opening_m": _C.PREMATURE_ACTION,
        "close": _C.PREMATURE_ACTION,
        "speed_mps": _C.DYNAMICS,
        "angular_speed_radps": _C.DYNAMICS,
        "relative_speed_mps": _C.DYNAMICS,
        "hold_margin_s": _C.DYNAMICS,
        "normal_force_n": _C.GRASP,
        "friction_margin_n": _C.GRASP,
    }
)


def check_category(name: str) -> ErrorCategory:
    """The category of an answer refused by check ``name``; an unknown name is an error of
    the code (a check added without its category), never a guess."""
    try:
        return CHECK_CATEGORIES[name]
    except KeyError:
        raise KeyError(f"check {name!r} has no category in CHECK_CATEGORIES") from None
