"""The waypoint controller: IK to tolerance, convergence, and unreachable poses refused."""

from __future__ import annotations

import pytest

from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.errors import UnreachableError
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import top_down_quat
from actionreasoning.world.models import Pose


def test_a_reachable_waypoint_is_reached(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    target = Pose(position_m=(0.5, 0.3, 0.25), quat_xyzw=top_down_quat(0.7))
    report = controller.execute(Waypoint(pose=target))
    assert report.converged
    assert report.position_error_m < 1e-3
    assert report.orientation_error_deg < 0.2


def test_a_linear_waypoint_keeps_the_tool_on_the_line(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    start = Pose(position_m=(0.5, -0.3, 0.30), quat_xyzw=top_down_quat(0.2))
    controller.execute(Waypoint(pose=start))
    end = Pose(position_m=(0.5, -0.3, 0.10), quat_xyzw=top_down_quat(0.2))
    knots = controller.plan(Waypoint(pose=end, path="linear"))
    assert len(knots) == 21  # one IK solution per centimetre
    for joints in knots:
        (x, y, _), _ = arm.forward(joints)
        assert abs(x - 0.5) < 1e-3 and abs(y + 0.3) < 1e-3


def test_gripper_commands_open_and_close(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    here = Pose(position_m=(0.5, 0.3, 0.3), quat_xyzw=top_down_quat(0.0))
    controller.execute(Waypoint(pose=here, gripper=GripperCommand.CLOSE))
    assert sum(scene.finger_positions()) == pytest.approx(0.06, abs=2e-3)
    controller.execute(Waypoint(pose=here, gripper=GripperCommand.OPEN))
    assert sum(scene.finger_positions()) == pytest.approx(0.16, abs=2e-3)


@pytest.mark.parametrize(
    "position",
    [(1.2, 0.0, 0.2), (0.1, 0.0, 0.05), (0.5, 0.0, 1.5)],
    ids=["too-far", "inside-the-base", "too-high"],
)
def test_an_unreachable_waypoint_is_refused(
    scene: Scene, arm: KinematicArm, position: tuple[float, float, float]
) -> None:
    controller = WaypointController(scene, arm)
    ticks = scene.ticks
    with pytest.raises(UnreachableError, match="out of reach"):
        controller.execute(Waypoint(pose=Pose(position_m=position, quat_xyzw=top_down_quat(0.0))))
    assert scene.ticks == ticks  # nothing was executed
