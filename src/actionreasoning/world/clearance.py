"""The answer to a clearance query, and how far the query looks.

The tools build the boxes (``world/boxes.py``) and read the answer; ``sim/collision.py``
computes it.
"""

from __future__ import annotations

from dataclasses import dataclass

#: Distances beyond this are not resolved: a clearance of this value means "at least".
SEARCH_DISTANCE_M = 0.25
#: A path is checked at poses this far apart: along a straight path, and in joint space
#: (the largest joint turn between two poses checked).
PATH_STEP_M = 0.01
JOINT_STEP_RAD = 0.05


@dataclass(frozen=True)
class Clearance:
    """The smallest distance found and between what."""

    distance_m: float
    between: str
