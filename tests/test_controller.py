"""The waypoint controller: IK to tolerance, convergence, and unreachable poses refused."""

from __future__ import annotations

import pytest
from conftest import pick_up
from pydantic import ValidationError

from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.errors import UnreachableError
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import quat_yaw, top_down_quat
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


def test_min_ticks_slows_a_move_and_never_speeds_it_up(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    start = Pose(position_m=(0.5, -0.3, 0.30), quat_xyzw=top_down_quat(0.2))
    end = Pose(position_m=(0.5, -0.3, 0.10), quat_xyzw=top_down_quat(0.2))
    controller.execute(Waypoint(pose=start))
    fastest = controller.execute(Waypoint(pose=end, path="linear"), settle=False).ticks
    controller.execute(Waypoint(pose=start, path="linear"))
    slow = controller.execute(Waypoint(pose=end, path="linear", min_ticks=4 * fastest), False)
    controller.execute(Waypoint(pose=start, path="linear"))
    asked_faster = controller.execute(Waypoint(pose=end, path="linear", min_ticks=1), False)
    assert slow.ticks == 4 * fastest
    assert asked_faster.ticks == fastest
    assert slow.position_error_m < 2e-3


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


def test_the_gripper_opens_to_a_requested_width(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    here = Pose(position_m=(0.5, 0.3, 0.3), quat_xyzw=top_down_quat(0.0))
    controller.execute(Waypoint(pose=here, gripper=GripperCommand.CLOSE))
    controller.execute(Waypoint(pose=here, gripper=GripperCommand.OPEN, gripper_opening_m=0.12))
    assert sum(scene.finger_positions()) == pytest.approx(0.12, abs=2e-3)


def test_inconsistent_waypoints_are_refused() -> None:
    here = Pose(position_m=(0.5, 0.3, 0.3), quat_xyzw=top_down_quat(0.0))
    with pytest.raises(ValidationError, match="goes with the gripper command 'open'"):
        Waypoint(pose=here, gripper=GripperCommand.CLOSE, gripper_opening_m=0.1)
    with pytest.raises(ValidationError, match="needs a linear path"):
        Waypoint(pose=here, stop_on_contact=0)
    with pytest.raises(ValidationError, match=r"less than or equal to 0\.16"):
        Waypoint(pose=here, gripper=GripperCommand.OPEN, gripper_opening_m=0.5)


def test_a_guarded_set_down_stops_when_the_brick_touches(scene: Scene, arm: KinematicArm) -> None:
    controller = WaypointController(scene, arm)
    (x, y, _), quat = scene.brick_pose(0)
    pick_up(controller, 0, quat_yaw(quat), lift_to_m=0.15)
    # 5 mm lower than where the brick meets the ground (and above the 2 cm safety floor).
    too_low = Pose(position_m=(x, y, 0.025), quat_xyzw=top_down_quat(quat_yaw(quat)))
    report = controller.execute(Waypoint(pose=too_low, path="linear", stop_on_contact=0))
    assert report.stopped_on_contact
    (_, _, z), _ = scene.brick_pose(0)
    assert z == pytest.approx(0.03, abs=2e-3)  # resting on the ground, still held
    assert scene.tcp_pose()[0][2] == pytest.approx(0.03, abs=3e-3)
    assert scene.support_force(0) > 2.0


def test_a_held_brick_is_no_transit_obstacle_however_far_it_slid(
    scene: Scene, arm: KinematicArm
) -> None:
    controller = WaypointController(scene, arm)
    _, quat = scene.brick_pose(0)
    pick_up(controller, 0, quat_yaw(quat), lift_to_m=0.30)
    assert scene.is_held(0) and not any(scene.is_held(i) for i in range(1, len(scene.bricks)))
    # As if it had slid 8 cm down the pads: past the distance rule, still pressed by both.
    tcp, _ = scene.tcp_pose()
    obstacles = controller._obstacles((tcp[0], tcp[1], tcp[2] + 0.08))
    assert 0 not in {obstacle.id for obstacle in obstacles}
    assert {obstacle.id for obstacle in obstacles} == set(range(1, len(scene.bricks)))
