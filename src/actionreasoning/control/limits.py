"""The waypoint controller's limits, apart from the controller so that a configuration
(``trial/config.py``) can name them without loading the simulator."""

from __future__ import annotations

from dataclasses import dataclass

from pydantic import NonNegativeFloat, PositiveFloat


@dataclass(frozen=True)
class ControllerLimits:
    """Peak speeds, durations and tolerances of the waypoint controller."""

    max_joint_speed_radps: PositiveFloat = 2.5
    max_linear_speed_mps: PositiveFloat = 0.15
    min_duration_s: NonNegativeFloat = 0.2
    settle_max_s: NonNegativeFloat = 2.0
    joint_tolerance_rad: PositiveFloat = 2e-3
    joint_speed_tolerance_radps: PositiveFloat = 0.02
    #: A guarded move stops when its brick's support carries this much: about twice a
    #: brick's weight, so a brick is pressed flat before the guard trips.
    contact_force_n: NonNegativeFloat = 30.0
    gripper_s: PositiveFloat = 0.625
