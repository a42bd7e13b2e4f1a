"""Grasp options: the two top-down grasps of a brick, each checked for a pick and a place.

For a brick and the target it is to go to, each grasp across the brick's short side is
checked as the agents will carry it out: whether the arm reaches the approach pose, the
grasp pose and the place pose over the target, how far the wrist turns, and the clearance
of the joint move to the approach and of the straight descent to the grasp.
"""

from __future__ import annotations

import math

from pydantic import Field

from actionreasoning.tools import formulas
from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.tools.collision import CollisionQuery, collision_check
from actionreasoning.tools.geometry import GraspQuery, brick_state, grasp_candidates, target_of
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import GRIPPER_GAP_M

#: The place pose checked is this far above the target centre.
PLACE_CHECK_ABOVE_M = 0.1


class GraspOptionsQuery(ToolModel):
    """A brick, the target it is to go to, and the opening the descent will use."""

    brick_id: int = Field(ge=0)
    target_index: int = Field(ge=0, description="The target it goes to.")
    descent_opening_m: float = Field(
        GRIPPER_GAP_M[1],
        ge=GRIPPER_GAP_M[0],
        le=GRIPPER_GAP_M[1],
        description="Opening while descending.",
    )


class GraspOption(ToolModel):
    """One top-down grasp, checked at pick and place."""

    gripper_yaw_deg: float
    approach_pose: Pose = Field(description="12 cm above the grasp pose.")
    grasp_pose: Pose = Field(description="At the brick's centre (half its height up).")
    reachable: bool = Field(description="The arm reaches both and the place pose.")
    wrist_deg: float | None = Field(
        description="Largest wrist-joint turn of the three (null if one is out of reach)."
    )
    approach_clearance_m: float = Field(description="Of the joint move to approach_pose.")
    descent_clearance_m: float = Field(description="Of the straight descent to grasp_pose.")


class GraspOptions(ToolModel):
    """Both grasps across the brick's short side (their yaws differ by 180 deg)."""

    options: tuple[GraspOption, GraspOption]


def grasp_options(context: ToolContext, query: GraspOptionsQuery) -> GraspOptions:
    """Both top-down grasps across a brick's width, checked for pick and place at a target."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    goal = target_of(state, query.target_index)
    x, y, z = goal.pose.position_m
    candidates = grasp_candidates(context, GraspQuery(brick_id=brick.id)).candidates
    options = []
    for candidate in candidates:
        approach = candidate.approach_pose
        grasp = formulas.grasp_pose(brick.pose, brick.size_m, approach.quat_xyzw)
        # The brick as it lies, held by this grasp, set on the target: the tool turns as the
        # brick must (a brick lying upside down would need the tool pointing up). The slot
        # pose's orientation; the place pose checked is PLACE_CHECK_ABOVE_M over the target.
        _, held = formulas.in_hand(approach, brick.pose)
        turn = formulas.slot_pose(goal.pose, (0.0, 0.0, 0.0), held).quat_xyzw
        place = Pose(position_m=(x, y, z + PLACE_CHECK_ABOVE_M), quat_xyzw=turn)
        solutions = [
            context.arm.solve(pose.position_m, pose.quat_xyzw)
            for pose in (approach, candidate.grasp_pose, place)
        ]
        reachable = all(s.reached for s in solutions)
        wrist = max(abs(s.joints_rad[6]) for s in solutions) if reachable else None
        to_approach = collision_check(
            context,
            CollisionQuery(
                pose=approach,
                path="joint",
                gripper_opening_m=state.robot.gripper_width_m,
                ignore_brick_id=brick.id,
            ),
        )
        descent = collision_check(
            context,
            CollisionQuery(
                pose=grasp,
                start_pose=approach,
                gripper_opening_m=query.descent_opening_m,
                ignore_brick_id=brick.id,
            ),
        )
        options.append(
            GraspOption(
                gripper_yaw_deg=candidate.gripper_yaw_deg,
                approach_pose=approach,
                grasp_pose=grasp,
                reachable=reachable and to_approach.reachable and descent.reachable,
                wrist_deg=None if wrist is None else math.degrees(wrist),
                approach_clearance_m=to_approach.clearance_m,
                descent_clearance_m=descent.clearance_m,
            )
        )
    return GraspOptions(options=tuple(options))


GRASP_OPTIONS = tool("grasp_options", grasp_options)
