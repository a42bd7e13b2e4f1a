"""What an agent observes of the scene: the measured poses (``state``), camera pictures
(``image``), or both.

In ``state`` the state block shows every brick's measured pose, as the paper's agents are
shown. In ``image`` it keeps the robot, the goal and the memory but no brick: each call
carries the cameras' pictures instead (``world/pictures.py``), and the prompt gives each
camera's intrinsics and pose, so that a pixel and its depth give a world point; agent 1
names no brick id, and the brick it picks is the one under its approach pose. In ``both``
each call carries the pictures and the state block keeps the poses. The gates'
measurements and refusals are the same in every mode: they are the robot's sensors, not
its eyes.
"""

from __future__ import annotations

from enum import StrEnum

from actionreasoning.errors import ConfigError


class Observation(StrEnum):
    """What an agent is shown of the scene."""

    STATE = "state"
    IMAGE = "image"
    BOTH = "both"

    @property
    def pictures(self) -> bool:
        """Whether each call carries the cameras' pictures."""
        return self is not Observation.STATE

    @property
    def poses(self) -> bool:
        """Whether the state block shows the bricks' measured poses."""
        return self is not Observation.IMAGE


DEFAULT_OBSERVATION = Observation.STATE


def load_observation(name: str) -> Observation:
    """The observation named ``name``; an unknown name is refused, naming the choices."""
    try:
        return Observation(name)
    except ValueError:
        choices = ", ".join(Observation)
        raise ConfigError(f"observe {str(name)[:40]!r}: not one of {choices}") from None
