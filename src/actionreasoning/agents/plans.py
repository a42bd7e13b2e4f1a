"""The pre-move checks: an answer's feasibility, judged before the arm moves.

Each check tests what its move needs, never equality with one canonical answer: the arm can
reach it, its way is clear, it is slow enough, and it forecasts what the next gate will
measure (a grip sigma_3 accepts, a seat within the success rule). Any answer the physics
allows passes. Each threshold is a row of the tolerance table (``world/tolerances.py``).
Like the gates (``gates.py``), each is a pure function of measured values that returns a
:class:`GateVerdict` whose feedback names value and threshold.

The grasp's geometry, which the approach, the descent and a corrected grasp share: the tool
points down and the pads close along its y axis. Closing, the coupled pads centre a brick
across its width but keep an offset along its length and its yaw (``bench/grip_centring.py``),
so sigma_3's forecast is the offset along the length and in height, and the yaw; an offset
across the width only has to leave the open pads room to pass the side walls.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.agents.feedback import Measured
from actionreasoning.agents.gates import Check, GateVerdict
from actionreasoning.tools.collision import CollisionReport
from actionreasoning.world.geometry import Vec3, quat_yaw, wrap_angle
from actionreasoning.world.models import BrickState, Pose
from actionreasoning.world.scene_spec import FINGERTIPS_BEYOND_TCP_M, PAD_LENGTH_M
from actionreasoning.world.tolerances import LIFT_SUPPORT_M, Tolerances


@dataclass(frozen=True)
class Grip:
    """A tool pose against a brick, in the brick's terms: the tool's offset from the brick's
    centre along its length, across its width and in height (m, brick centre minus tool),
    the yaw between pads and brick modulo a half turn (deg), and how far the tool's axis is
    from pointing down (deg)."""

    along_m: float
    across_m: float
    up_m: float
    yaw_deg: float
    tilt_deg: float
    world_offset_m: Vec3

    @classmethod
    def of(cls, tool: Pose, brick: BrickState) -> Grip:
        """The grip of ``tool`` on ``brick`` as measured."""
        rotation = Rotation.from_quat(tool.quat_xyzw)
        offset = np.subtract(brick.pose.position_m, tool.position_m)
        x_axis, y_axis, z_axis = (rotation.apply(axis) for axis in np.eye(3))
        yaw = wrap_angle(2.0 * (quat_yaw(brick.pose.quat_xyzw) - quat_yaw(tool.quat_xyzw))) / 2
        down = math.degrees(math.acos(max(-1.0, min(1.0, -float(z_axis[2])))))
        return cls(
            along_m=float(np.dot(offset[:2], _unit(x_axis[:2]))),
            across_m=float(np.dot(offset[:2], _unit(y_axis[:2]))),
            up_m=float(offset[2]),
            yaw_deg=math.degrees(yaw),
            tilt_deg=down,
            world_offset_m=(float(offset[0]), float(offset[1]), float(offset[2])),
        )

    @property
    def sigma3_offset_m(self) -> float:
        """The offset sigma_3 will measure once the pads close: along and in height."""
        return math.hypot(self.along_m, self.up_m)

    def pad_room_m(self, opening_m: float, width_m: float) -> float:
        """The room left between each open pad and the side wall it passes: half the
        opening, less the offset across the width and the half-width the pads meet, the
        brick turned by the yaw under pads PAD_LENGTH_M long."""
        yaw = math.radians(min(abs(self.yaw_deg), 89.0))
        meets = width_m / 2.0 / math.cos(yaw) + PAD_LENGTH_M / 2.0 * math.tan(yaw)
        return opening_m / 2.0 - abs(self.across_m) - meets


def _unit(vector: np.ndarray) -> np.ndarray:
    norm = float(np.linalg.norm(vector))
    return vector / norm if norm > 1e-9 else vector


def crossing(start: Pose, end: Pose, brick: BrickState) -> Pose:
    """The pose on the straight way from ``start`` to ``end`` (yaw turned evenly) where the
    fingertips reach the brick's top; ``start`` if they are below it there already."""
    top = brick.pose.position_m[2] + brick.size_m[2] / 2.0 + FINGERTIPS_BEYOND_TCP_M
    z0, z1 = start.position_m[2], end.position_m[2]
    share = 0.0 if z0 <= top or z0 <= z1 else min(1.0, (z0 - top) / (z0 - z1))
    position = np.add(start.position_m, share * np.subtract(end.position_m, start.position_m))
    turn = Rotation.from_quat(end.quat_xyzw) * Rotation.from_quat(start.quat_xyzw).inv()
    part = Rotation.from_rotvec(share * turn.as_rotvec()) * Rotation.from_quat(start.quat_xyzw)
    quat = tuple(float(q) for q in part.as_quat())
    return Pose(
        position_m=(float(position[0]), float(position[1]), float(position[2])), quat_xyzw=quat
    )


def way_down_room_m(start: Pose, grasp: Pose, brick: BrickState, opening_m: float) -> float:
    """The least room between an open pad and a side wall on the straight way from
    ``start`` down to ``grasp``: at the two ends of the part below the brick's top (the
    room there is convex in the way's length, so its least is at an end)."""
    width = brick.size_m[1]
    return min(
        Grip.of(pose, brick).pad_room_m(opening_m, width)
        for pose in (crossing(start, grasp, brick), grasp)
    )


def _grip_checks(grip: Grip, room_m: float, tol: Tolerances) -> tuple[Check, ...]:
    """A grip sigma_3 will accept, reached with the pads passing the side walls."""
    return (
        Check("pointing_down_deg", grip.tilt_deg, tol.eps_g_deg, at_most=True),
        Check("grip_offset_m", grip.sigma3_offset_m, tol.eps_g_m, at_most=True),
        Check("grip_yaw_deg", abs(grip.yaw_deg), tol.eps_g_deg, at_most=True),
        Check("pad_room_m", room_m, tol.pad_room_m, at_most=False),
    )


def _grip_measured(grip: Grip) -> Measured:
    dx, dy, dz = grip.world_offset_m
    return Measured(e_x_m=dx, e_y_m=dy, e_z_m=dz, e_theta_deg=grip.yaw_deg)


def approach_plan(
    approach: Pose, brick: BrickState, widest_m: float, tol: Tolerances
) -> GateVerdict:
    """Agent 1's approach: a hover clear above the brick (fingertips ``hover_clearance_m``
    over its top), from which a descent that keeps the orientation (the grasp's yaw is
    sigma_3's) goes straight down to the brick's centre with the pads, open to
    ``widest_m``, passing its side walls. Where over the brick it hovers is free."""
    centre = Pose(
        position_m=(*brick.pose.position_m[:2], brick.pose.position_m[2]),
        quat_xyzw=approach.quat_xyzw,
    )
    at_centre = Grip.of(centre, brick)
    here = Grip.of(approach, brick)
    top = brick.pose.position_m[2] + brick.size_m[2] / 2.0
    hover = approach.position_m[2] - FINGERTIPS_BEYOND_TCP_M - top
    room = way_down_room_m(approach, centre, brick, widest_m)
    return GateVerdict(
        "pre_grasp_plan",
        (
            Check("hover_clearance_m", hover, tol.hover_clearance_m, at_most=False),
            Check("pointing_down_deg", here.tilt_deg, tol.eps_g_deg, at_most=True),
            Check("grip_yaw_deg", abs(at_centre.yaw_deg), tol.eps_g_deg, at_most=True),
            Check("pad_room_m", room, tol.pad_room_m, at_most=False),
        ),
        measured=Measured(
            e_x_m=here.world_offset_m[0], e_y_m=here.world_offset_m[1], e_theta_deg=here.yaw_deg
        ),
    )


def grip_plan(
    gate: str,
    start: Pose,
    grasp: Pose,
    brick: BrickState,
    opening_m: float,
    way: CollisionReport,
    tol: Tolerances,
    least_opening_m: float | None = None,
) -> GateVerdict:
    """A descent (or a corrected grasp) from ``start`` to ``grasp`` with the pads open to
    ``opening_m``: a grip sigma_3 accepts, the pads passing the side walls all the way down,
    the way reachable and clear; for a descent, an opening of at least
    ``least_opening_m`` (the width + delta sigma_2 measures)."""
    grip = Grip.of(grasp, brick)
    opening = (
        ()
        if least_opening_m is None
        else (Check("opening_m", opening_m, least_opening_m, at_most=False),)
    )
    return GateVerdict(
        gate,
        (
            *opening,
            *_grip_checks(grip, way_down_room_m(start, grasp, brick, opening_m), tol),
            *path_checks(way, tol, "way_"),
        ),
        measured=_grip_measured(grip).model_copy(
            update={"clearance_m": way.clearance_m, "closest": way.closest}
        ),
    )


def lift_plan(
    sideways_m: tuple[float, float],
    rise_m: float,
    turn_deg: float,
    speed_mps: float,
    path: CollisionReport,
    bottom_clearance_m: float,
    tol: Tolerances,
) -> GateVerdict:
    """Before a lift moves: no drag while the brick still touches its support (the tool's
    sideways travel and turn over the first LIFT_SUPPORT_M of rise within ``lift_drag_m``
    and ``lift_drag_deg``; a straight line spreads them evenly over the rise), a mean speed
    no faster than v_lift (a faster lift rolls the brick as it breaks away), collision-free
    from LIFT_SUPPORT_M up, and the held brick's bottom ending c_min above every other
    brick's top. ``sideways_m`` is the lift's end minus the tool's position (x, y); the
    feedback's correction is its opposite."""
    share = 1.0 if rise_m <= LIFT_SUPPORT_M else LIFT_SUPPORT_M / rise_m
    return GateVerdict(
        "lift_plan",
        (
            Check("drag_m", math.hypot(*sideways_m) * share, tol.lift_drag_m, at_most=True),
            Check("drag_turn_deg", turn_deg * share, tol.lift_drag_deg, at_most=True),
            Check("speed_mps", speed_mps, tol.v_lift_mps, at_most=True),
            *path_checks(path, tol),
            Check("bottom_clearance_m", bottom_clearance_m, tol.c_min_m, at_most=False),
        ),
        measured=Measured(
            e_x_m=-sideways_m[0],
            e_y_m=-sideways_m[1],
            move_speed_mps=speed_mps,
            clearance_m=path.clearance_m,
            closest=path.closest,
        ),
    )


def release_plan(opening_m: float, width_m: float) -> GateVerdict:
    """Agent 6: the pads open to at least the brick's width, so that they let go of it.
    Where the tool returns to is free: sigma_6 checks the way there."""
    return GateVerdict("release_plan", (Check("opening_m", opening_m, width_m, at_most=False),))


def path_checks(report: CollisionReport, tol: Tolerances, prefix: str = "") -> tuple[Check, ...]:
    """A path reachable and clear, no overlap beyond what sensing noise can show."""
    return (
        Check(f"{prefix}reachable", float(report.reachable), 1.0, at_most=False),
        Check(f"{prefix}clearance_m", report.clearance_m, -tol.overlap_m, at_most=False),
    )
