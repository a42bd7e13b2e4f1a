"""Geometric tools over the measured WorldState: alignment, grasp candidates, support.

Frames: world (origin at the arm's base on the ground, z up); angles in degrees in the
outputs; lengths in metres.
"""

from __future__ import annotations

import math

from pydantic import Field

from actionreasoning.errors import ToolError
from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import (
    quat_yaw,
    rotation_deg,
    tilt_deg,
    top_down_quat,
    wrap_angle,
)
from actionreasoning.world.models import BrickState, Pose, TargetBrick, WorldState
from actionreasoning.world.support import carriers, centre_is_held

GROUND_TOL_M = 2e-3


class BrickQuery(ToolModel):
    """Which brick to look at."""

    brick_id: int = Field(ge=0)


class AlignmentQuery(ToolModel):
    """A brick and the pattern target it is compared with."""

    brick_id: int = Field(ge=0)
    target_index: int = Field(ge=0, description="Index of a target in the goal pattern.")


class AlignmentErrors(ToolModel):
    """How far a brick is from its target (world frame)."""

    e_xy_m: tuple[float, float] = Field(description="Target centre minus brick centre, x and y.")
    e_xy_norm_m: float = Field(description="Planar distance between the centres.")
    e_theta_deg: float = Field(description="Target yaw minus brick yaw, wrapped to [-180, 180).")
    d_perp_m: float = Field(description="Brick bottom minus target bottom; > 0 above its seat.")
    tilt_deg: float = Field(description="Angle between the brick's z axis and world up.")
    rotation_deg: float = Field(
        description="Angle of the rotation from the target's orientation to the brick's "
        "(the success rule's rotation error)."
    )
    offset_m: float = Field(description="Distance between the centres (the success rule's).")


class GraspQuery(ToolModel):
    """Options of a top-down grasp."""

    brick_id: int = Field(ge=0)
    approach_height_m: float = Field(
        0.12, gt=0.0, le=0.3, description="Height of the approach pose above the grasp pose."
    )
    side_clearance_m: float = Field(
        0.02, ge=0.0, le=0.03, description="Free space wanted on each side of the brick."
    )


class GraspCandidate(ToolModel):
    """One top-down grasp across the brick's short side."""

    gripper_yaw_deg: float
    grasp_pose: Pose = Field(description="Tool centre point at the brick centre.")
    approach_pose: Pose = Field(description="Straight above the grasp pose.")
    opening_needed_m: float = Field(description="Brick width plus clearance on both sides.")


class GraspCandidates(ToolModel):
    """The two yaw choices of a grasp across the short side (they differ by 180 deg)."""

    brick_id: int
    grasp_axis_xy: tuple[float, float] = Field(
        description="Unit vector the fingers close along (the brick's short side)."
    )
    candidates: tuple[GraspCandidate, GraspCandidate]


class SupportReport(ToolModel):
    """What a brick rests on."""

    brick_id: int
    on_ground: bool
    carriers: tuple[int, ...] = Field(description="Ids of the bricks whose top face carries it.")
    contact_area_m2: float
    centre_supported: bool = Field(description="Centre over the hull of its contact areas.")
    tilt_deg: float


def brick_state(state: WorldState, brick_id: int) -> BrickState:
    """The brick ``brick_id`` of ``state``, or a ToolError naming the ids there are."""
    try:
        return state.brick(brick_id)
    except KeyError:
        ids = ", ".join(str(b.id) for b in state.bricks)
        raise ToolError(f"no brick with id {brick_id} (ids: {ids})") from None


def target_of(state: WorldState, index: int) -> TargetBrick:
    """The target ``index`` of the goal, or a ToolError naming how many there are."""
    if not 0 <= index < len(state.goal.targets):
        raise ToolError(f"no target {index} (the pattern has {len(state.goal.targets)})")
    return state.goal.targets[index]


def _box(brick: BrickState) -> Box:
    return Box(brick.pose.position_m, brick.pose.quat_xyzw, brick.size_m, id=brick.id)


def alignment_errors(context: ToolContext, query: AlignmentQuery) -> AlignmentErrors:
    """Planar offset, yaw error and height above the seat of a brick against a target."""
    brick = brick_state(context.state, query.brick_id)
    return alignment_of(brick.pose, brick.size_m, target_of(context.state, query.target_index))


def alignment_of(
    pose: Pose, size_m: tuple[float, float, float], target: TargetBrick
) -> AlignmentErrors:
    """The alignment errors of a brick of ``size_m`` at ``pose`` against ``target``."""
    (bx, by, bz), (tx, ty, tz) = pose.position_m, target.pose.position_m
    e_theta = wrap_angle(quat_yaw(target.pose.quat_xyzw) - quat_yaw(pose.quat_xyzw))
    return AlignmentErrors(
        e_xy_m=(tx - bx, ty - by),
        e_xy_norm_m=math.hypot(tx - bx, ty - by),
        e_theta_deg=math.degrees(e_theta),
        d_perp_m=(bz - size_m[2] / 2.0) - (tz - target.size_m[2] / 2.0),
        tilt_deg=tilt_deg(pose.quat_xyzw),
        rotation_deg=rotation_deg(target.pose.quat_xyzw, pose.quat_xyzw),
        offset_m=math.dist(pose.position_m, target.pose.position_m),
    )


def grasp_candidates(context: ToolContext, query: GraspQuery) -> GraspCandidates:
    """Top-down grasps closing across the brick's short side, at its yaw and turned 180 deg."""
    brick = brick_state(context.state, query.brick_id)
    yaw = quat_yaw(brick.pose.quat_xyzw)
    x, y, z = brick.pose.position_m
    candidates = tuple(
        GraspCandidate(
            gripper_yaw_deg=math.degrees(wrap_angle(yaw + flip)),
            grasp_pose=Pose(position_m=(x, y, z), quat_xyzw=top_down_quat(yaw + flip)),
            approach_pose=Pose(
                position_m=(x, y, z + query.approach_height_m), quat_xyzw=top_down_quat(yaw + flip)
            ),
            opening_needed_m=brick.size_m[1] + 2.0 * query.side_clearance_m,
        )
        for flip in (0.0, math.pi)
    )
    return GraspCandidates(
        brick_id=brick.id,
        grasp_axis_xy=(-math.sin(yaw), math.cos(yaw)),
        candidates=candidates,
    )


def support_contact(context: ToolContext, query: BrickQuery) -> SupportReport:
    """The ground or the bricks under a brick, their contact area, and if its centre is held."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    box = _box(brick)
    contacts = carriers(box, [_box(b) for b in state.bricks])
    on_ground = abs(box.bottom_m) <= GROUND_TOL_M
    areas = [area for _, area in contacts]
    return SupportReport(
        brick_id=brick.id,
        on_ground=on_ground,
        carriers=tuple(other.id for other, _ in contacts),
        contact_area_m2=box.footprint.area if on_ground else float(sum(a.area for a in areas)),
        centre_supported=on_ground or (bool(areas) and centre_is_held(box, areas)),
        tilt_deg=tilt_deg(brick.pose.quat_xyzw),
    )


ALIGNMENT = tool("alignment_errors", alignment_errors)
SUPPORT = tool("support_contact", support_contact)
