"""What refuses an answer: the rungs of the ablation ladder.

Every verdict a build records is one of three kinds (:func:`kind_of`): validation of the
answer as data (schema, completeness, workspace, ids) and the controller's reach, which
every rung enforces; the pre-move checks (``*_plan``, ``pre_grasp_choice``), which test an
answer's feasibility before anything moves; and the gates sigma_1..sigma_6 of the paper. A
rung (:class:`Verification`) says which of the last two refuse. A verdict a rung does not
enforce is still measured and recorded (``enforced`` false in the transcript), so a run
shows what the other checks would have caught; its answer runs as given.
"""

from __future__ import annotations

from enum import StrEnum

#: The gates judged on what a move did, after it ran; every other verdict is judged before
#: the arm moves.
AFTER_MOVE_GATES = frozenset(
    {"sigma2_descent", "sigma3_grasp", "sigma4_lift", "sigma5_placement", "sigma6_at_rest"}
)


class CheckKind(StrEnum):
    """What a verdict is: validation, a pre-move check or a gate."""

    VALIDATION = "validation"
    PLAN = "plan"
    GATE = "gate"


class Verification(StrEnum):
    """A rung of the ablation ladder: which verdicts refuse an answer (validation always)."""

    FULL = "full"  # the gates and the pre-move checks: the method as designed
    GATES = "gates"  # sigma_1..sigma_6 only; the pre-move checks are recorded
    CHECKS = "checks"  # the pre-move checks only; the gates are recorded
    NONE = "none"  # validation only (the single agent's rung)

    def enforces(self, gate: str) -> bool:
        """Whether this rung refuses an answer whose verdict ``gate`` failed."""
        kind = kind_of(gate)
        if kind is CheckKind.VALIDATION:
            return True
        if kind is CheckKind.GATE:
            return self in (Verification.FULL, Verification.GATES)
        return self in (Verification.FULL, Verification.CHECKS)


def kind_of(gate: str) -> CheckKind:
    """The kind of the verdict named ``gate``."""
    if gate.startswith("sigma"):
        return CheckKind.GATE
    if gate.endswith("_answer") or gate == "controller":
        return CheckKind.VALIDATION
    return CheckKind.PLAN


def judged_after_move(gate: str) -> bool:
    """Whether the verdict ``gate`` is judged on a move that already ran."""
    return gate in AFTER_MOVE_GATES
