"""Collision tool: clearance of the arm at a pose, or along a straight tool path.

Obstacles are the ground and every brick except the one being grasped; a brick the
gripper holds (status ``grasped``) moves with the gripper and is checked too.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field
from scipy.spatial.transform import Rotation, Slerp

from actionreasoning.errors import UnreachableError
from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.tools.formulas import carried, in_hand, rolled_in_hand
from actionreasoning.world.boxes import Box
from actionreasoning.world.clearance import (
    JOINT_STEP_RAD,
    PATH_STEP_M,
    SEARCH_DISTANCE_M,
    Clearance,
)
from actionreasoning.world.models import (
    BrickState,
    BrickStatus,
    Pose,
    WorldState,
    highest_under,
)
from actionreasoning.world.scene_spec import GRIPPER_GAP_M


class CollisionQuery(ToolModel):
    """A tool pose, optionally the start of a straight path to it, and the gripper opening."""

    pose: Pose = Field(description="Tool pose at the end of the move.")
    start_pose: Pose | None = Field(
        None, description="Where the move starts (linear: else only `pose` is checked)."
    )
    path: Literal["linear", "joint"] = Field(
        "linear", description="joint: a joint move, from where the arm is if no start_pose."
    )
    gripper_opening_m: float = Field(GRIPPER_GAP_M[1], ge=GRIPPER_GAP_M[0], le=GRIPPER_GAP_M[1])
    ignore_brick_id: int | None = Field(
        None, ge=0, description="A brick left out (the one being grasped or released)."
    )
    ignore_brick_at_m: tuple[float, float] | None = Field(
        None,
        description="A point (x, y) on the ground (m): the brick whose footprint holds it is "
        "left out, as by ignore_brick_id, for a brick known by where it lies.",
    )
    held_roll_turn_deg: float = Field(
        0.0,
        ge=-90.0,
        le=90.0,
        description="The held brick checked turned this much further in the hand (deg, about "
        "the pads' axis): as it will sit at the end of the move (Formulas: roll rate).",
    )


class CollisionReport(ToolModel):
    """The smallest clearance found (m; negative is penetration) and where."""

    reachable: bool = Field(description="The arm reaches every pose checked.")
    collision_free: bool = Field(description="Reachable and clearance > 0 everywhere.")
    clearance_m: float = Field(
        description=f"Least distance (< 0: overlap), at most {SEARCH_DISTANCE_M:g}."
    )
    closest: str = Field(description="The two things at that distance.")
    poses_checked: int


def _left_out(state: WorldState, query: CollisionQuery) -> int | None:
    """The brick the query leaves out: by id, or the one under its point."""
    if query.ignore_brick_at_m is None:
        return query.ignore_brick_id
    under = highest_under(state.bricks, *query.ignore_brick_at_m)
    return None if under is None else under.id


def _obstacles(state: WorldState, ignore: int | None) -> tuple[list[Box], BrickState | None]:
    held = next(
        (b for b in state.bricks if b.status == BrickStatus.GRASPED and b.id != ignore), None
    )
    boxes = [
        Box(b.pose.position_m, b.pose.quat_xyzw, b.size_m, id=b.id)
        for b in state.bricks
        if b.id != ignore and b is not held
    ]
    return boxes, held


def _path(query: CollisionQuery) -> list[Pose]:
    if query.start_pose is None:
        return [query.pose]
    start = np.asarray(query.start_pose.position_m)
    end = np.asarray(query.pose.position_m)
    steps = max(1, math.ceil(float(np.linalg.norm(end - start)) / PATH_STEP_M))
    slerp = Slerp(
        [0.0, 1.0], Rotation.from_quat([query.start_pose.quat_xyzw, query.pose.quat_xyzw])
    )
    return [
        Pose(position_m=tuple(start + s * (end - start)), quat_xyzw=tuple(slerp(s).as_quat()))
        for s in np.linspace(0.0, 1.0, steps + 1)
    ]


def _held_box(state: WorldState, held: BrickState, tool_pose: Pose, roll_turn_deg: float) -> Box:
    """The held brick carried rigidly from its measured grip, turned ``roll_turn_deg``
    further about the pads' axis, to ``tool_pose``."""
    grip = rolled_in_hand(*in_hand(state.robot.ee_pose, held.pose), roll_turn_deg)
    pose = carried(tool_pose, *grip)
    return Box(pose.position_m, pose.quat_xyzw, held.size_m, id=held.id)


def collision_check(context: ToolContext, query: CollisionQuery) -> CollisionReport:
    """Clearance of arm, gripper and held brick from the ground and the other bricks."""
    obstacles, held = _obstacles(context.state, _left_out(context.state, query))
    worst = Clearance(math.inf, "")
    try:
        configurations = _configurations(context, query)
    except UnreachableError as error:
        return CollisionReport(
            reachable=False,
            collision_free=False,
            clearance_m=0.0,
            closest=str(error),
            poses_checked=0,
        )
    opening = query.gripper_opening_m / 2.0
    for joints in configurations:
        held_box = None
        if held is not None:
            position, quat = context.arm.forward(joints)
            at = Pose(position_m=position, quat_xyzw=quat)
            held_box = _held_box(context.state, held, at, query.held_roll_turn_deg)
        found = context.collisions.clearance(joints, opening, obstacles, held_box)
        worst = found if found.distance_m < worst.distance_m else worst
    return CollisionReport(
        reachable=True,
        collision_free=worst.distance_m > 0.0,
        clearance_m=worst.distance_m,
        closest=worst.between,
        poses_checked=len(configurations),
    )


def _configurations(context: ToolContext, query: CollisionQuery) -> list[tuple[float, ...]]:
    """Arm joint angles along the motion the query describes (UnreachableError if IK fails)."""
    if query.path == "joint":
        here = context.state.robot.joint_positions_rad
        start = np.asarray(
            here if query.start_pose is None else _solve(context, query.start_pose, here)
        )
        end = np.asarray(_solve(context, query.pose, None))
        steps = max(1, math.ceil(float(np.max(np.abs(end - start))) / JOINT_STEP_RAD))
        return [tuple(start + s * (end - start)) for s in np.linspace(0.0, 1.0, steps + 1)]
    configurations: list[tuple[float, ...]] = []
    for pose in _path(query):
        configurations.append(_solve(context, pose, configurations[-1] if configurations else None))
    return configurations


def _solve(context: ToolContext, pose: Pose, seed: tuple[float, ...] | None) -> tuple[float, ...]:
    solution = context.arm.solve(pose.position_m, pose.quat_xyzw, seed)
    if not solution.reached:
        x, y, z = pose.position_m
        raise UnreachableError(f"no IK solution at ({x:.3f}, {y:.3f}, {z:.3f})")
    return solution.joints_rad


COLLISION = tool("collision_check", collision_check)
