"""Placement tools: where the held brick sits in the hand, the tool pose that sets it on a
target as it sits there (``solve`` tier), and the alignment errors a proposed tool pose
would give (``check`` tier).

The pose in the hand is the brick's measured pose in the tool frame (x along the pads'
faces, y the axis the pads close along, z pointing down out of the gripper). The slot
pose carries that grip rigidly: the tool pose at which the brick's centre, yaw and level
match the target's, tilting the tool by the brick's roll in the hand.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.tools.collision import CollisionQuery, collision_check
from actionreasoning.tools.formulas import carried, in_hand, rolled_in_hand, slot_pose
from actionreasoning.tools.geometry import (
    AlignmentErrors,
    BrickQuery,
    alignment_of,
    brick_state,
    target_of,
)
from actionreasoning.world.geometry import axis_angle_deg
from actionreasoning.world.models import BrickStatus, Pose

#: The way down is checked to this far above the seat: the set-down ends in contact.
SEAT_CLEARANCE_M = 0.003


class HeldPose(ToolModel):
    """A brick's pose in the tool frame."""

    held: bool
    offset_in_hand_m: tuple[float, float, float] = Field(description="Centre, tool frame.")
    quat_in_hand_xyzw: tuple[float, float, float, float] = Field(
        description="[1,0,0,0]: level under the tool, aligned."
    )
    tilt_in_hand_deg: float = Field(description="Roll in the hand (0 to 90).")


class PlacementQuery(ToolModel):
    """The held brick, its target, and how the tool gets over the slot."""

    brick_id: int = Field(ge=0)
    target_index: int = Field(ge=0)
    approach: Literal["joint", "linear"] = Field(
        "joint", description="The move over the slot: joint to carry, linear once over it."
    )
    roll_turn_deg: float = Field(
        0.0,
        ge=-90.0,
        le=90.0,
        description="How much further the brick rolls in the hand by touch-down (deg; "
        "Formulas: roll rate): the slot is for the brick so turned.",
    )


class PlacementPose(ToolModel):
    """The slot pose for the held brick, and whether the way there is clear."""

    slot_pose: Pose
    tilt_in_hand_deg: float = Field(description="Roll in the hand (0 to 90).")
    reachable: bool
    way_clearance_m: float = Field(description="Over the slot, then down to 3 mm above it.")
    closest: str = Field(description="The two things that close.")


def held_pose(context: ToolContext, query: BrickQuery) -> HeldPose:
    """A brick's pose in the tool frame and its roll in the hand."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    tool_pose = state.robot.ee_pose
    offset, turn = in_hand(tool_pose, brick.pose)
    return HeldPose(
        held=brick.status == BrickStatus.GRASPED,
        offset_in_hand_m=offset,
        quat_in_hand_xyzw=turn,
        tilt_in_hand_deg=axis_angle_deg(brick.pose.quat_xyzw, tool_pose.quat_xyzw),
    )


def placement_pose(context: ToolContext, query: PlacementQuery) -> PlacementPose:
    """The tool pose that sets the held brick, as it sits in the hand, level on a target."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    tool_pose = state.robot.ee_pose
    grip = rolled_in_hand(*in_hand(tool_pose, brick.pose), query.roll_turn_deg)
    slot = slot_pose(target_of(state, query.target_index).pose, *grip)
    quat = slot.quat_xyzw
    x, y, z = slot.position_m
    above = Pose(position_m=(x, y, max(z, tool_pose.position_m[2])), quat_xyzw=quat)
    seat = Pose(position_m=(x, y, z + SEAT_CLEARANCE_M), quat_xyzw=quat)
    opening = state.robot.gripper_width_m
    over = (
        CollisionQuery(pose=above, path="joint", gripper_opening_m=opening)
        if query.approach == "joint"
        else CollisionQuery(pose=above, start_pose=tool_pose, gripper_opening_m=opening)
    )
    # The way down with the brick as it will sit at touch-down.
    down = CollisionQuery(
        pose=seat,
        start_pose=above,
        gripper_opening_m=opening,
        held_roll_turn_deg=query.roll_turn_deg,
    )
    reports = [collision_check(context, q) for q in (over, down)]
    worst = min(reports, key=lambda r: r.clearance_m if r.reachable else -np.inf)
    return PlacementPose(
        slot_pose=slot,
        tilt_in_hand_deg=axis_angle_deg(brick.pose.quat_xyzw, tool_pose.quat_xyzw),
        reachable=all(r.reachable for r in reports),
        way_clearance_m=worst.clearance_m,
        closest=worst.closest,
    )


class PlacementCheckQuery(ToolModel):
    """The held brick, its target and a tool pose to set it down at."""

    brick_id: int = Field(ge=0)
    target_index: int = Field(ge=0)
    pose: Pose = Field(description="The tool pose proposed for the set-down.")
    roll_turn_deg: float = Field(
        0.0,
        ge=-90.0,
        le=90.0,
        description="How much further the brick rolls in the hand by touch-down (deg).",
    )


def placement_check(context: ToolContext, query: PlacementCheckQuery) -> AlignmentErrors:
    """The alignment errors of the held brick against its target were it set down with the
    tool at ``pose``, as it sits in the hand now turned ``roll_turn_deg`` further."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    goal = target_of(state, query.target_index)
    grip = rolled_in_hand(*in_hand(state.robot.ee_pose, brick.pose), query.roll_turn_deg)
    return alignment_of(carried(query.pose, *grip), brick.size_m, goal)


HELD_POSE = tool("held_pose", held_pose)
PLACEMENT_POSE = tool("placement_pose", placement_pose)
PLACEMENT_CHECK = tool("placement_check", placement_check)
