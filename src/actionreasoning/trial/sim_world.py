"""The simulator behind the orchestrator's World protocol."""

from __future__ import annotations

from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.eyes import shown_pictures
from actionreasoning.sim.perceive import Sensor
from actionreasoning.tools.base import ToolContext
from actionreasoning.world.models import GoalPattern, Pose, Progress, WorldState
from actionreasoning.world.motion import Motion
from actionreasoning.world.pictures import Picture


class SimWorld:
    """Observe, run tools, move and grip in a PyBullet scene."""

    def __init__(self, controller: WaypointController, goal: GoalPattern, sensor: Sensor) -> None:
        self.controller = controller
        self.goal = goal
        self.sensor = sensor
        self.sensing = sensor.sensing
        self.collisions = CollisionChecker(controller.arm)

    def observe(self, progress: Progress) -> WorldState:
        """Measure the world now (the moment before every agent call: the trial's wall-time
        budget is checked here)."""
        self.controller.scene.check_wall_time()
        return self.sensor.perceive(self.goal, progress)

    def look(self) -> tuple[Picture, ...]:
        """The cameras' pictures now, rendered by TinyRenderer (the scene is not stepped)."""
        return shown_pictures(self.controller.scene.client)

    def tools(self, state: WorldState) -> ToolContext:
        """Tools on the kinematic copy of the arm, for a measured state."""
        return ToolContext(state=state, arm=self.controller.arm, collisions=self.collisions)

    def move(self, waypoint: WaypointProposal, stop_on_contact: int | None = None) -> Motion:
        """Execute a gated waypoint and report what was measured."""
        duration = waypoint.duration_s
        return self.controller.execute(
            Waypoint(
                pose=Pose(position_m=waypoint.position_m, quat_xyzw=waypoint.quat_xyzw),
                path=waypoint.path,
                min_ticks=None if duration is None else self.controller.scene.ticks_for(duration),
                stop_on_contact=stop_on_contact,
            )
        )

    def grip(self, opening_m: float | None) -> None:
        """Close the gripper (None) or open it to ``opening_m``."""
        if opening_m is None:
            self.controller.grip(GripperCommand.CLOSE)
        else:
            self.controller.grip(GripperCommand.OPEN, opening_m)
