"""What the orchestrator needs from the world, as a protocol: observe, run tools, move, grip.

The simulator side implements it (``trial/sim_world.py``); the agents never touch PyBullet.
"""

from __future__ import annotations

from typing import Protocol

from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.tools.base import ToolContext
from actionreasoning.world.models import Progress, Sensing, WorldState
from actionreasoning.world.motion import Motion
from actionreasoning.world.pictures import Picture


class World(Protocol):
    """The orchestrator's view of the robot and the scene."""

    #: How noisy the measurements are and how far catalogue values may be off.
    sensing: Sensing

    def observe(self, progress: Progress) -> WorldState:
        """Measure the world now."""
        ...

    def look(self) -> tuple[Picture, ...]:
        """The cameras' pictures now (``world/pictures.py``: SHOWN, in its order)."""
        ...

    def tools(self, state: WorldState) -> ToolContext:
        """The tool context for a measured state."""
        ...

    def move(self, waypoint: WaypointProposal, stop_on_contact: int | None = None) -> Motion:
        """Move the tool to a gated waypoint (raises UnreachableError if IK misses it)."""
        ...

    def grip(self, opening_m: float | None) -> None:
        """Close the gripper (None) or open it to ``opening_m``."""
        ...
