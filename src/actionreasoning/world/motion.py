"""What a move did, as measured after it: the controller reports it, the agents read it."""

from __future__ import annotations

from dataclasses import dataclass

#: The longest a single move may be asked to take (an answer's ``duration_s``).
MAX_MOVE_S = 30.0
#: Mean speed of a carry with a brick in the hand (the placement's duration formula): a brick
#: creeps and rolls in the hand with time, so a faster carry rolls it less
#: (``bench/lift_roll.py``: carries at 5, 10, 20 and 40 cm/s rolled 16 bricks more than
#: 10 deg 7, 3, 1 and 1 times).
CARRY_SPEED_MPS = 0.20


@dataclass(frozen=True)
class Motion:
    """The measured result of executing one waypoint."""

    ticks: int
    converged: bool
    #: A guarded (set-down) move stopped early: its brick's support carried the contact force.
    stopped_on_contact: bool
    position_error_m: float
    orientation_error_deg: float
