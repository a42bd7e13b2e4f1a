"""Typed world model S_t and goal G (DESIGN section 3).

Everything the reasoning layer knows about the world is one :class:`WorldState`: plain
pydantic models with a JSON schema, round-trip serialisable. Units: metres, kilograms,
newtons, seconds; orientations are quaternions (x, y, z, w) in the world frame, whose
origin is the arm's base on the ground with z up.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw, top_down_quat
from actionreasoning.world.physics import GRIP_FORCE_N, PAD_FRICTION


class BrickStatus(StrEnum):
    """Where a brick is, as measured."""

    IN_PICK_AREA = "in_pick_area"  # lying flat in the pick area: on the ground or a stack
    GRASPED = "grasped"
    PLACED = "placed"  # on a target it was released at
    DROPPED = "dropped"  # anywhere else, lying flat
    TOPPLED = "toppled"  # tilted
    COVERED = "covered"  # in the pick area under another brick: free once that is taken
    QUEUED = "queued"  # in a feeder's queue, out of reach: fed when the last brick is taken


class Supply(StrEnum):
    """Where the bricks wait to be picked (a pattern's ``supply``)."""

    SCATTERED = "scattered"  # lying on the ground at random poses in the pick area
    PALLET = "pallet"  # stacked in layers on a pallet in the pick area: the top of a stack
    FEEDER = "feeder"  # one at a time at a fixed pose, the next fed when it is taken


class _Model(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class Pose(_Model):
    """A rigid pose in the world frame."""

    position_m: Vec3
    quat_xyzw: QuatXYZW = (0.0, 0.0, 0.0, 1.0)


#: Where the tool waits between bricks, pointing down at yaw 0, clear of every brick.
READY_POSE = Pose(position_m=(0.45, -0.25, 0.40), quat_xyzw=top_down_quat(0.0))


def is_pickable(status: BrickStatus) -> bool:
    """Free to be picked: in the pick area, or dropped and lying flat, on the ground or
    fallen onto other bricks (picked off the build, it is cleared from it)."""
    return status in (BrickStatus.IN_PICK_AREA, BrickStatus.DROPPED)


class PadContact(_Model):
    """A brick that touches a finger pad, and its force on each pad."""

    brick_id: int
    normal_n: tuple[float, float] = Field(
        description="Normal contact force of this brick on the left and right finger pads."
    )
    tangential_n: tuple[float, float] = Field(
        description="Friction (tangential) force of this brick on each pad."
    )


class RobotState(_Model):
    """The arm and gripper as measured by the simulator."""

    ee_pose: Pose = Field(description="Tool centre point (between the finger pads).")
    joint_positions_rad: tuple[float, ...]
    gripper_width_m: float = Field(description="Gap between the finger pads.")
    finger_depth_m: float = Field(description="Finger pad length below the tool centre point.")
    finger_forces_n: tuple[float, float] = Field(
        description="Normal contact force of the held brick on the left and right finger pads."
    )
    finger_tangential_n: tuple[float, float] = Field(
        (0.0, 0.0), description="Friction (tangential) force on each pad from the held brick."
    )
    pad_contacts: tuple[PadContact, ...] = Field(
        (),
        description="Every brick that touches a finger pad, held or not, with its forces on "
        "the pads; a brick not listed touches neither pad.",
    )
    finger_friction: float = Field(
        PAD_FRICTION, description="Friction coefficient of the finger pads."
    )
    grip_force_limit_n: float = Field(GRIP_FORCE_N, description="Largest grip force per pad.")
    ee_linear_velocity_mps: Vec3 = (0.0, 0.0, 0.0)
    ee_angular_velocity_radps: Vec3 = (0.0, 0.0, 0.0)
    ready_pose: Pose = Field(
        READY_POSE, description="Where the tool returns to after each brick, clear of them all."
    )


class BrickState(_Model):
    """One brick as measured by the robot's sensors."""

    id: int
    size_m: Vec3
    mass_kg: float = Field(description="Catalogue mass; see sensing.mass_tolerance.")
    friction: float = Field(
        description="Catalogue lateral friction coefficient; see sensing.friction_tolerance."
    )
    pose: Pose
    linear_velocity_mps: Vec3 = (0.0, 0.0, 0.0)
    angular_velocity_radps: Vec3 = (0.0, 0.0, 0.0)
    status: BrickStatus = BrickStatus.IN_PICK_AREA

    @property
    def pickable(self) -> bool:
        """Free to be picked: in the pick area, or dropped and lying flat (:func:`is_pickable`)."""
        return is_pickable(self.status)


class TargetBrick(_Model):
    """One brick of a goal pattern: where its centre goes, in build order."""

    index: int
    pose: Pose
    size_m: Vec3


class GoalPattern(_Model):
    """The goal G: target brick poses in the world frame, in build order."""

    name: str
    gap_m: float | None = None
    brick_size_m: Vec3
    targets: tuple[TargetBrick, ...]
    supply: Supply = Supply.SCATTERED

    @property
    def sizes(self) -> tuple[Vec3, ...]:
        """The pattern's distinct brick sizes, in order of first use."""
        return tuple(dict.fromkeys(t.size_m for t in self.targets))

    def fits(self, brick_size_m: Vec3, target: int) -> bool:
        """Whether a brick measured at ``brick_size_m`` is of target ``target``'s size."""
        return nearest_size(brick_size_m, self.sizes) == self.targets[target].size_m


def nearest_size(size_m: Vec3, sizes: Sequence[Vec3]) -> Vec3:
    """Of ``sizes``, the one nearest to ``size_m`` (by the largest edge difference): the size
    a measured brick is of. Its edges vary far less than two catalogue sizes differ, so no
    threshold is needed."""
    return min(sizes, key=lambda size: max(abs(a - b) for a, b in zip(size, size_m, strict=True)))


class Progress(_Model):
    """Building progress: which bricks are placed and what is being done now."""

    placed_ids: tuple[int, ...] = ()
    current_brick: int | None = None
    step: str | None = None


class Sensing(_Model):
    """How far measurements and catalogue values may be from the truth (sensor datasheet)."""

    position_std_m: float = Field(0.0, description="Noise (std) of a brick position, per axis.")
    yaw_std_deg: float = Field(0.0, description="Noise (std) of a brick yaw.")
    force_rel_std: float = Field(0.0, description="Relative noise (std) of the pad forces.")
    mass_tolerance: float = Field(0.0, description="A brick's mass is within +- this share.")
    friction_tolerance: float = Field(0.0, description="Its friction is within +- this share.")


def highest_under(bricks: Sequence[BrickState], x: float, y: float) -> BrickState | None:
    """Of ``bricks``, the highest whose footprint holds the point (x, y): the brick there,
    on top of any it lies on; None if none does."""
    under = [brick for brick in bricks if footprint_holds(brick, x, y)]
    return max(under, key=lambda brick: brick.pose.position_m[2], default=None)


def footprint_holds(brick: BrickState, x: float, y: float) -> bool:
    """Whether ``brick``'s footprint, as measured, holds the point (x, y) on the ground."""
    cx, cy, _ = brick.pose.position_m
    yaw = quat_yaw(brick.pose.quat_xyzw)
    along = (x - cx) * math.cos(yaw) + (y - cy) * math.sin(yaw)
    across = -(x - cx) * math.sin(yaw) + (y - cy) * math.cos(yaw)
    return abs(along) <= brick.size_m[0] / 2.0 and abs(across) <= brick.size_m[1] / 2.0


class WorldState(_Model):
    """The serialized world S_t handed to reasoners."""

    time_s: float
    robot: RobotState
    bricks: tuple[BrickState, ...]
    goal: GoalPattern
    progress: Progress = Progress()
    sensing: Sensing = Sensing()

    def brick(self, brick_id: int) -> BrickState:
        """The brick with ``brick_id`` (KeyError if there is none)."""
        for brick in self.bricks:
            if brick.id == brick_id:
                return brick
        raise KeyError(f"no brick with id {brick_id}")

    @property
    def obstacles(self) -> tuple[BrickState, ...]:
        """Placed bricks: obstacles for every later move."""
        placed = set(self.progress.placed_ids)
        return tuple(b for b in self.bricks if b.id in placed)
