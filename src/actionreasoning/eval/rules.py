"""The rules of the benchmark: the methods compared, each trial's seed, and success.

Free of the simulator and the reasoners, so reading results (``summary.py``, ``report``)
needs neither.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from actionreasoning.eval.results import BrickResult, PlacementMetrics
from actionreasoning.world.geometry import Vec3


class Method(StrEnum):
    """The reasoning methods a trial can run."""

    AGENTS = "agents"
    SINGLE_AGENT = "single-agent"
    CLASSICAL = "classical"


def trial_seed(run_seed: int, trial: int) -> int:
    """The seed of trial ``trial``: derived from the run seed and the index only."""
    return int(np.random.SeedSequence([run_seed, trial]).generate_state(1)[0])


@dataclass(frozen=True)
class SuccessRule:
    """A trial succeeds when every brick is within these limits of its target and at rest."""

    max_center_offset_cm: float = 2.0
    max_rotation_error_deg: float = 5.0
    max_speed_mps: float = 0.01
    max_angular_speed_radps: float = 0.05

    def is_placed(self, brick: BrickResult | PlacementMetrics) -> bool:
        """Whether a brick (its result or its metrics) is within the offset and rotation
        limits of its target."""
        return (
            brick.center_offset_cm <= self.max_center_offset_cm
            and brick.rotation_error_deg <= self.max_rotation_error_deg
        )

    def is_at_rest(self, linear_mps: Vec3, angular_radps: Vec3) -> bool:
        """Whether a brick moving with these velocities counts as at rest."""
        return (
            float(np.linalg.norm(linear_mps)) <= self.max_speed_mps
            and float(np.linalg.norm(angular_radps)) <= self.max_angular_speed_radps
        )
