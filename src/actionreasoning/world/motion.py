"""What a move did, as measured after it: the controller reports it, the agents read it."""

from __future__ import annotations

from dataclasses import dataclass

#: The longest a single move may be asked to take (an answer's ``duration_s``).
MAX_MOVE_S = 30.0


@dataclass(frozen=True)
class Motion:
    """The measured result of executing one waypoint."""

    ticks: int
    converged: bool
    #: A guarded (set-down) move stopped early: its brick's support carried the contact force.
    stopped_on_contact: bool
    position_error_m: float
    orientation_error_deg: float
