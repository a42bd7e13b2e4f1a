"""What an agent observes of the scene: the measured poses (``state``), or the poses and
camera pictures (``both``).

In ``state`` the state block shows every brick's measured pose, as the paper's agents are
shown. In ``both`` each call also carries the cameras' pictures (``world/pictures.py``)
and the prompt gives each camera's intrinsics and pose, so that a pixel and its depth give
a world point. The gates' measurements and refusals are the same in every mode: they are
the robot's sensors, not its eyes.
"""

from __future__ import annotations

from enum import StrEnum

from actionreasoning.errors import ConfigError


class Observation(StrEnum):
    """What an agent is shown of the scene."""

    STATE = "state"
    BOTH = "both"

    @property
    def pictures(self) -> bool:
        """Whether each call carries the cameras' pictures."""
        return self is not Observation.STATE


DEFAULT_OBSERVATION = Observation.STATE


def load_observation(name: str) -> Observation:
    """The observation named ``name``; an unknown name is refused, naming the choices."""
    try:
        return Observation(name)
    except ValueError:
        choices = ", ".join(Observation)
        raise ConfigError(f"observe {str(name)[:40]!r}: not one of {choices}") from None
