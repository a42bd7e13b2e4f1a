"""What the tools need from the arm's kinematic model and its collision checker, and no more.

``sim/kinematics.KinematicArm`` and ``sim/collision.CollisionChecker`` provide these, so the
tools, and the agents and reasoners above them, never import the simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol, runtime_checkable

from actionreasoning.world.boxes import Box
from actionreasoning.world.clearance import Clearance
from actionreasoning.world.geometry import Joints, QuatXYZW, Vec3


class IKResult(Protocol):
    """Joint angles for a tool pose, how well they reach it and whether that is within
    the solver's tolerances."""

    @property
    def joints_rad(self) -> tuple[float, ...]: ...

    @property
    def position_error_m(self) -> float: ...

    @property
    def orientation_error_deg(self) -> float: ...

    @property
    def joint_limit_margin_rad(self) -> float: ...

    @property
    def reached(self) -> bool: ...


@runtime_checkable
class ArmModel(Protocol):
    """Forward and inverse kinematics of the arm's tool centre point."""

    def forward(self, joints_rad: Joints) -> tuple[Vec3, QuatXYZW]:
        """Tool centre point pose (position m, quaternion xyzw) for arm joint angles."""
        ...

    def solve(
        self, position_m: Vec3, quat_xyzw: QuatXYZW, rest_rad: Joints | None = None
    ) -> IKResult:
        """Joint angles putting the tool centre point at the pose; ``rest_rad`` seeds them."""
        ...


@runtime_checkable
class ClearanceChecker(Protocol):
    """Clearance of the arm, its gripper and a held brick from boxes and the ground."""

    def clearance(
        self,
        joints_rad: Joints,
        finger_half_width_m: float,
        obstacles: Sequence[Box],
        held: Box | None = None,
    ) -> Clearance:
        """Smallest distance (m, negative: overlap) of the arm at ``joints_rad`` and ``held``
        to ``obstacles`` and the ground."""
        ...
