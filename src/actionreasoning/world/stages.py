"""The stages a brick goes through, from the approach to the retreat after its release.

The six agents are named by their stages; the carry over the slot (``transfer``) and the
way up after the release (``retreat``) are stages of their own for the single agent and
the classical script, and names of pictures for all.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class Stage(StrEnum):
    """A stage of a brick's cycle, in the order a brick goes through them."""

    PRE_GRASP = "pre_grasp"
    DESCENT = "descent"
    GRASP = "grasp"
    LIFT = "lift"
    TRANSFER = "transfer"
    PLACEMENT = "placement"
    RELEASE = "release"
    RETREAT = "retreat"


@dataclass(frozen=True)
class StageEvent:
    """A stage a method finished for brick ``brick``, for observers: snapshots, videos,
    recordings and the Gym env's reward."""

    brick: int
    stage: str
