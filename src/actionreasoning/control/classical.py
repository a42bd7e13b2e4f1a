"""The paper's classical baseline (section IV-C-1): a minimal hand-scripted pick and place.

What an engineer writes without event handling: fixed approach, lift and release heights,
fixed step counts, the release at a fixed height above the target, no contact or collision
checks and no feedback. It does what any careful script would do up front: it places brick k
on target k in build order, and picks the grasp yaw (brick yaw or +180 deg) that keeps the
wrist joint small at both ends so the wrist never spins through its limit.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.sim.perceive import Sensor
from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw, top_down_quat
from actionreasoning.world.models import GoalPattern, Pose
from actionreasoning.world.stages import Stage, StageEvent


@dataclass(frozen=True)
class ClassicalScript:
    """The fixed numbers of the script (metres and seconds)."""

    approach_height_m: float = 0.12
    transfer_height_m: float = 0.30
    release_height_m: float = 0.01
    transfer_s: float = 2.0
    vertical_s: float = 1.0


class ClassicalController:
    """Runs the fixed script brick by brick."""

    def __init__(
        self,
        controller: WaypointController,
        sensor: Sensor,
        script: ClassicalScript = ClassicalScript(),
    ) -> None:
        self.controller = controller
        self.sensor = sensor
        self.script = script

    def grasp_yaws(self, position: Vec3, quat: QuatXYZW, target: Pose) -> tuple[float, float]:
        """Gripper yaw at pick and at place (rad) for a brick measured at ``position``,
        ``quat``: the pair with the smaller wrist angles."""
        brick_yaw = quat_yaw(quat)
        turn = quat_yaw(target.quat_xyzw) - brick_yaw
        pick_yaw = min(
            (brick_yaw, brick_yaw + math.pi),
            key=lambda yaw: max(
                abs(self._wrist(position, yaw)), abs(self._wrist(target.position_m, yaw + turn))
            ),
        )
        return pick_yaw, pick_yaw + turn

    def _wrist(self, position: Vec3, yaw: float) -> float:
        arm = self.controller.arm
        above = (position[0], position[1], self.script.transfer_height_m)
        return arm.solve(above, top_down_quat(yaw)).joints_rad[6]

    def place_brick(self, brick: int, target: Pose) -> Iterator[Stage]:
        """Pick brick ``brick`` and put it on ``target``; yields each finished stage's name."""
        s, run = self.script, self.controller.execute
        position, quat = self.sensor.brick_pose(brick)
        pick_yaw, place_yaw = self.grasp_yaws(position, quat, target)
        transfer = self.controller.scene.ticks_for(s.transfer_s)
        vertical = self.controller.scene.ticks_for(s.vertical_s)
        px, py, pz = position
        tx, ty, tz = target.position_m

        def at(x: float, y: float, z: float, yaw: float) -> Pose:
            return Pose(position_m=(x, y, z), quat_xyzw=top_down_quat(yaw))

        steps = [
            (
                Stage.PRE_GRASP,
                Waypoint(
                    pose=at(px, py, pz + s.approach_height_m, pick_yaw),
                    gripper=GripperCommand.OPEN,
                    ticks=transfer,
                ),
            ),
            (
                Stage.DESCENT,
                Waypoint(pose=at(px, py, pz, pick_yaw), path="linear", ticks=vertical),
            ),
            (
                Stage.GRASP,
                Waypoint(pose=at(px, py, pz, pick_yaw), gripper=GripperCommand.CLOSE, ticks=1),
            ),
            (
                Stage.LIFT,
                Waypoint(
                    pose=at(px, py, s.transfer_height_m, pick_yaw),
                    path="linear",
                    ticks=vertical,
                ),
            ),
            (
                Stage.TRANSFER,
                Waypoint(pose=at(tx, ty, s.transfer_height_m, place_yaw), ticks=transfer),
            ),
            (
                Stage.PLACEMENT,
                Waypoint(
                    pose=at(tx, ty, tz + s.release_height_m, place_yaw),
                    path="linear",
                    ticks=vertical,
                ),
            ),
            (
                Stage.RELEASE,
                Waypoint(
                    pose=at(tx, ty, tz + s.release_height_m, place_yaw),
                    gripper=GripperCommand.OPEN,
                    ticks=1,
                ),
            ),
            (
                Stage.RETREAT,
                Waypoint(
                    pose=at(tx, ty, s.transfer_height_m, place_yaw),
                    path="linear",
                    ticks=vertical,
                ),
            ),
        ]
        for stage, waypoint in steps:
            run(waypoint, settle=False)
            yield stage


def run_classical(
    controller: WaypointController,
    sensor: Sensor,
    goal: GoalPattern,
    on_stage: Callable[[StageEvent], None] | None = None,
) -> None:
    """Build ``goal`` with the classical script: brick k goes to target k."""
    script = ClassicalController(controller, sensor)
    for target in goal.targets:
        for stage in script.place_brick(target.index, target.pose):
            if on_stage is not None:
                on_stage(StageEvent(brick=target.index, stage=stage))
