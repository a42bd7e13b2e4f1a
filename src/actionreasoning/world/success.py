"""The success rule of the benchmark: when a brick counts as placed and at rest.

It lives with the world model because the gates derive their tolerances from it
(``world/tolerances.py``): a gate must never pass what this rule fails.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Protocol

import numpy as np
from pydantic import Field, NonNegativeFloat, PositiveFloat

from actionreasoning.world.geometry import Vec3


class Placement(Protocol):
    """A brick's error against its target (a results line's brick, or trial means)."""

    @property
    def center_offset_cm(self) -> float: ...

    @property
    def rotation_error_deg(self) -> float: ...


@dataclass(frozen=True)
class SuccessRule:
    """A trial succeeds when every brick is within these limits of its target and at rest."""

    # excess() divides by the two placement limits; a rotation error is at most 180 deg.
    max_center_offset_cm: PositiveFloat = 2.0
    max_rotation_error_deg: Annotated[float, Field(gt=0.0, le=180.0)] = 5.0
    max_speed_mps: NonNegativeFloat = 0.01
    max_angular_speed_radps: NonNegativeFloat = 0.05

    def is_placed(self, brick: Placement) -> bool:
        """Whether a brick (its result or its metrics) is within the offset and rotation
        limits of its target."""
        return (
            brick.center_offset_cm <= self.max_center_offset_cm
            and brick.rotation_error_deg <= self.max_rotation_error_deg
        )

    def excess(self, brick: Placement) -> float:
        """How far a brick is from its target in units of the rule's limits: the larger of
        its offset and its rotation error, each over its limit (above 1: not placed)."""
        return max(
            brick.center_offset_cm / self.max_center_offset_cm,
            brick.rotation_error_deg / self.max_rotation_error_deg,
        )

    def is_at_rest(self, linear_mps: Vec3, angular_radps: Vec3) -> bool:
        """Whether a brick moving with these velocities counts as at rest."""
        return (
            float(np.linalg.norm(linear_mps)) <= self.max_speed_mps
            and float(np.linalg.norm(angular_radps)) <= self.max_angular_speed_radps
        )
