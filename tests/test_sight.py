"""The image tier's eyes for the built-in policy (reasoners/sight.py): from real rendered
pictures alone, the free bricks where they lie, none on a built target, and a held brick's
roll in the hand and offset between the pads."""

from __future__ import annotations

import math

import pybullet as p
import pytest

from actionreasoning.agents.feedback import FailedCheck, Measured, Refusal
from actionreasoning.agents.memory import PlacedBrick, StepDecision, TaskMemory
from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.agents.view import RobotView, StateView, TargetView
from actionreasoning.reasoners.sight import SEEN_ID_BASE, is_seen, seen_view
from actionreasoning.sim.eyes import shown_pictures
from actionreasoning.sim.scene import Scene
from actionreasoning.tools import formulas
from actionreasoning.world.geometry import quat_yaw, rotation_deg, top_down_quat, yaw_quat
from actionreasoning.world.models import BrickStatus, Pose
from actionreasoning.world.stages import Stage

SIZE = (0.2, 0.095, 0.06)


def image_view(tool: Pose, targets: tuple[TargetView, ...]) -> StateView:
    """An image-tier state block: the robot and the targets, no brick."""
    return StateView(
        robot=RobotView(tool_pose=tool, gripper_width_m=0.14), bricks=(), targets=targets
    )


def target(index: int, position: tuple[float, float, float]) -> TargetView:
    pose = Pose(position_m=position, quat_xyzw=yaw_quat(0.0))
    return TargetView(index=index, pose=pose, rests_on=(), size_m=SIZE)


def test_the_free_bricks_are_found_where_they_lie_and_a_built_one_is_left_out(
    scene: Scene,
) -> None:
    """Six bricks in the pick area; one target far off and one under brick 2's own centre,
    built: brick 2 is the brick placed there, and is left out."""
    under, _ = scene.brick_pose(2)
    targets = (target(0, (0.6, 0.2, 0.03)), target(1, under))
    memory = TaskMemory(placed=(PlacedBrick(brick_id=2, target_index=1),))
    view = seen_view(
        image_view(Pose(position_m=(0.45, -0.25, 0.4)), targets),
        memory,
        shown_pictures(scene.client),
    )
    assert all(is_seen(b.id) and b.id >= SEEN_ID_BASE for b in view.bricks)
    assert all(b.status is BrickStatus.IN_PICK_AREA and b.size_m == SIZE for b in view.bricks)
    for brick in range(len(scene.bricks)):
        position, quat = scene.brick_pose(brick)
        near = [b for b in view.bricks if math.dist(b.pose.position_m[:2], position[:2]) < 0.05]
        if brick == 2:
            assert near == []
            continue
        assert len(near) == 1, brick
        assert math.dist(near[0].pose.position_m, position) < 0.004
        turn = (quat_yaw(near[0].pose.quat_xyzw) - quat_yaw(quat) + math.pi / 2) % math.pi
        assert abs(math.degrees(turn - math.pi / 2)) < 1.0


def test_a_brick_lying_on_a_target_not_yet_built_is_numbered_first(scene: Scene) -> None:
    """The brick numbered last lies on target 1's slot, unbuilt: it is in that target's
    way, and is numbered first, for the policy, taking bricks by number, to pick first."""
    tool = Pose(position_m=(0.45, -0.25, 0.4))
    pictures = shown_pictures(scene.client)
    far = (target(0, (0.6, 0.2, 0.03)),)
    *_, last = sorted(
        seen_view(image_view(tool, far), TaskMemory(), pictures).bricks, key=lambda b: b.id
    )
    on = last.pose.position_m
    view = seen_view(image_view(tool, (*far, target(1, on))), TaskMemory(), pictures)
    first, *others = sorted(view.bricks, key=lambda b: b.id)
    assert first.pose.position_m == on
    assert len(others) == len(scene.bricks) - 1


def test_a_brick_put_down_out_of_sight_lies_under_the_tool_that_let_go(scene: Scene) -> None:
    """After a put-down (memory.regrasps), before agent 1 chooses again: where no find lies
    within a brick's length of the tool, the current brick lies under it, on the ground,
    turned as the tool is; where one does, the pictures show it and nothing is added."""
    targets = (target(0, (0.6, 0.2, 0.03)),)
    memory = TaskMemory(current_brick=7, current_target=0, regrasps=1)
    pictures = shown_pictures(scene.client)
    tool = Pose(position_m=(0.3, 0.45, 0.3), quat_xyzw=top_down_quat(math.radians(30.0)))
    view = seen_view(image_view(tool, targets), memory, pictures)
    put_down = view.brick(7)
    assert put_down.status is BrickStatus.DROPPED and put_down.size_m == SIZE
    assert put_down.pose.position_m == pytest.approx((0.3, 0.45, SIZE[2] / 2.0))
    assert math.degrees(quat_yaw(put_down.pose.quat_xyzw)) == pytest.approx(30.0)
    over, _ = scene.brick_pose(3)
    seen = Pose(position_m=(over[0], over[1], 0.3))
    assert 7 not in [b.id for b in seen_view(image_view(seen, targets), memory, pictures).bricks]
    approach = WaypointProposal(position_m=(0.3, 0.45, 0.3), quat_xyzw=tool.quat_xyzw)
    chosen = StepDecision(agent=Stage.PRE_GRASP, target_index=0, waypoint=approach, passed=True)
    again = memory.model_copy(update={"this_brick": (chosen,)})
    shown = seen_view(image_view(tool, targets), again, pictures).bricks
    assert all(b.status is not BrickStatus.DROPPED for b in shown)


def test_a_put_down_brick_refused_under_the_tool_is_not_taken_to_lie_there_again(
    scene: Scene,
) -> None:
    """Agent 1's approach over the put-down brick was refused: no brick lies under it (it
    fell or rolled away on the way down). It is not put there again; a refusal of that
    kind before the put-down does not count."""
    targets = (target(0, (0.6, 0.2, 0.03)),)
    tool = Pose(position_m=(0.3, 0.45, 0.3), quat_xyzw=top_down_quat(0.0))
    pictures = shown_pictures(scene.client)
    put_down = Refusal(agent="lift", gate="sigma4_lift")
    missed = Refusal(
        agent="pre_grasp",
        gate="pre_grasp_choice",
        failed=(FailedCheck(name="brick_under_approach", value=0.0, relation=">=", threshold=1),),
    )
    for refusals, there in (((missed, put_down), True), ((put_down, missed), False)):
        memory = TaskMemory(current_brick=7, current_target=0, regrasps=1, refusals=refusals)
        shown = [b.id for b in seen_view(image_view(tool, targets), memory, pictures).bricks]
        assert (7 in shown) is there
        assert len(shown) == len(scene.bricks) + there


@pytest.mark.parametrize(
    ("roll_deg", "offset_m"),
    [(0.0, (0.0, 0.0, 0.0)), (17.0, (0.012, 0.0015, 0.004)), (-38.0, (-0.008, -0.002, 0.01))],
)
def test_a_held_brick_is_seen_rolled_and_shifted_as_it_sits_in_the_hand(
    scene: Scene, roll_deg: float, offset_m: tuple[float, float, float]
) -> None:
    """Brick 0 put in the open hand of the arm at its ready pose, rolled about the pads'
    axis and shifted in the hand: after the grasp, the brick the view shows is there,
    within a millimetre and half a degree."""
    position, quat = scene.tcp_pose()
    tool = Pose(position_m=position, quat_xyzw=quat)
    square = formulas.in_hand(
        Pose(position_m=(0, 0, 0), quat_xyzw=top_down_quat(0.0)),
        Pose(position_m=(0, 0, 0), quat_xyzw=yaw_quat(0.0)),
    )[1]
    held = formulas.carried(tool, offset_m, formulas.rolled_in_hand((0, 0, 0), square, roll_deg)[1])
    p.resetBasePositionAndOrientation(
        scene.bricks[0], held.position_m, held.quat_xyzw, physicsClientId=scene.client
    )
    approach = WaypointProposal(position_m=position, quat_xyzw=quat)
    memory = TaskMemory(
        current_brick=0,
        current_target=0,
        this_brick=(
            StepDecision(agent=Stage.PRE_GRASP, target_index=0, waypoint=approach, passed=True),
            StepDecision(agent=Stage.GRASP, close=True, passed=True),
        ),
    )
    view = seen_view(
        image_view(tool, (target(0, (0.6, 0.2, 0.03)),)), memory, shown_pictures(scene.client)
    )
    brick = view.brick(0)
    assert brick.status is BrickStatus.GRASPED
    assert math.dist(brick.pose.position_m, held.position_m) < 0.001
    assert rotation_deg(brick.pose.quat_xyzw, held.quat_xyzw) < 0.5


def test_the_brick_under_the_tool_is_where_refused_descents_measured_it(scene: Scene) -> None:
    """Agent 1 chose the brick under the tool; where the pictures show no top face there
    (the arm over a stack can hide it) it lies on the ground, and each refused descent in a
    row shifts it by what its gate measured, in height too."""
    tool = Pose(position_m=(0.3, 0.45, 0.3), quat_xyzw=top_down_quat(0.0))
    approach = WaypointProposal(position_m=(0.3, 0.45, 0.3), quat_xyzw=tool.quat_xyzw)
    chosen = StepDecision(agent=Stage.PRE_GRASP, target_index=0, waypoint=approach, passed=True)
    missed = [
        Refusal(agent="descent", gate="descent_plan", measured=Measured(e_x_m=dx, e_z_m=dz))
        for dx, dz in ((0.004, 0.06), (-0.001, 0.002))
    ]
    pictures = shown_pictures(scene.client)
    targets = (target(0, (0.6, 0.2, 0.03)),)
    for refusals, expected in (((), (0.3, 0.45, 0.03)), (missed, (0.303, 0.45, 0.092))):
        memory = TaskMemory(
            current_brick=7, current_target=0, this_brick=(chosen,), refusals=tuple(refusals)
        )
        view = seen_view(image_view(tool, targets), memory, pictures)
        assert view.brick(7).pose.position_m == pytest.approx(expected)
