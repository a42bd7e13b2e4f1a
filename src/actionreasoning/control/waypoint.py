"""The waypoint controller: an SE(3) tool pose plus a gripper command becomes joint motion.

A waypoint is solved by IK (null-space rest pose, refined to tolerance), interpolated in
joint space with a smooth profile over K_t servo ticks, and optionally followed by a
convergence wait. ``linear`` waypoints move the tool centre point on a straight line
(IK every centimetre). An unreachable waypoint raises :class:`UnreachableError`; it is
never silently approximated.
"""

from __future__ import annotations

import math
from enum import StrEnum
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.spatial.transform import Rotation, Slerp

from actionreasoning.control.limits import ControllerLimits
from actionreasoning.control.safety import SafetyLimits, check_motion
from actionreasoning.errors import UnreachableError
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.robot_model import FINGER_MAX_M, FINGER_MIN_M
from actionreasoning.sim.scene import Scene
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import Vec3
from actionreasoning.world.models import Pose
from actionreasoning.world.motion import Motion

LINEAR_STEP_M = 0.01
#: How close a brick's centre is to the tool centre point when the brick is the one in the hand.
HELD_DISTANCE_M = 0.06
#: Peak over mean speed of the minimum-jerk profile: durations derived from speed limits
#: use it so that the limits hold at the peak.
MIN_JERK_PEAK = 1.875


class GripperCommand(StrEnum):
    """What the gripper does once the arm has reached the waypoint."""

    OPEN = "open"
    CLOSE = "close"
    HOLD = "hold"


class Waypoint(BaseModel):
    """A target tool pose, a gripper command and how to get there."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    pose: Pose
    gripper: GripperCommand = GripperCommand.HOLD
    path: Literal["joint", "linear"] = "joint"
    ticks: int | None = Field(None, ge=1, description="K_t; derived from the speed limits if None.")
    min_ticks: int | None = Field(
        None, ge=1, description="Least K_t: slower than the speed limits need, never faster."
    )
    gripper_opening_m: float | None = Field(
        None, ge=2 * FINGER_MIN_M, le=2 * FINGER_MAX_M, description="Gap to open to (OPEN only)."
    )
    stop_on_contact: int | None = Field(
        None,
        ge=0,
        description="Brick id: a linear move stops as soon as something other than the "
        "fingers carries more than the contact force limit of this brick (a guarded set-down).",
    )

    @model_validator(mode="after")
    def _consistent(self) -> Waypoint:
        if self.gripper_opening_m is not None and self.gripper is not GripperCommand.OPEN:
            raise ValueError("gripper_opening_m goes with the gripper command 'open'")
        if self.stop_on_contact is not None and self.path != "linear":
            raise ValueError("stop_on_contact needs a linear path")
        return self


class WaypointController:
    """Drives the scene's arm through waypoints."""

    def __init__(
        self,
        scene: Scene,
        arm: KinematicArm,
        limits: ControllerLimits = ControllerLimits(),
        safety: SafetyLimits = SafetyLimits(),
    ) -> None:
        self.scene = scene
        self.arm = arm
        self.limits = limits
        self.safety = safety

    def solve(self, pose: Pose, seed_rad: np.ndarray | None = None) -> np.ndarray:
        """Arm joints for a tool pose; raises :class:`UnreachableError` if IK misses it."""
        solution = self.arm.solve(pose.position_m, pose.quat_xyzw, seed_rad)
        if not solution.reached:
            x, y, z = pose.position_m
            raise UnreachableError(
                f"pose ({x:.3f}, {y:.3f}, {z:.3f}) m is out of reach: IK leaves "
                f"{solution.position_error_m * 1000:.1f} mm and "
                f"{solution.orientation_error_deg:.2f} deg of error"
            )
        return np.array(solution.joints_rad)

    def plan(self, waypoint: Waypoint) -> list[np.ndarray]:
        """Joint-space knots from the current arm targets to the waypoint."""
        start = self.scene.arm_targets
        if waypoint.path == "joint":
            return [start, self.solve(waypoint.pose)]
        position, quat = self.arm.forward(start)
        goal = np.asarray(waypoint.pose.position_m)
        distance = float(np.linalg.norm(goal - np.asarray(position)))
        steps = max(1, math.ceil(distance / LINEAR_STEP_M))
        slerp = Slerp([0.0, 1.0], Rotation.from_quat([quat, waypoint.pose.quat_xyzw]))
        knots = [start]
        for s in np.linspace(0.0, 1.0, steps + 1)[1:]:
            pose = Pose(
                position_m=tuple(np.asarray(position) + s * (goal - np.asarray(position))),
                quat_xyzw=tuple(slerp(s).as_quat()),
            )
            knots.append(self.solve(pose, knots[-1]))
        return knots

    def execute(self, waypoint: Waypoint, settle: bool = True) -> Motion:
        """Move to the waypoint, apply its gripper command, and report the measured result.

        The planned path is checked against the safety limits first; a violation raises
        ``TrialAborted`` before the arm moves. After the move the scene is checked for a
        physics blow-up.
        """
        knots = self.plan(waypoint)
        total = self._duration(knots, waypoint)
        self._check_safety(knots, waypoint, total)
        ticks, stopped = self._move(knots, waypoint, total)
        converged = True
        if settle:
            extra, converged = self._settle(self.scene.arm_targets)
            ticks += extra
        ticks += self._actuate_gripper(waypoint.gripper, waypoint.gripper_opening_m)
        self.scene.check_physics()
        position, quat = self.scene.tcp_pose()
        relative = Rotation.from_quat(quat).inv() * Rotation.from_quat(waypoint.pose.quat_xyzw)
        return Motion(
            ticks=ticks,
            converged=converged,
            stopped_on_contact=stopped,
            position_error_m=float(np.linalg.norm(np.subtract(position, waypoint.pose.position_m))),
            orientation_error_deg=float(np.degrees(relative.magnitude())),
        )

    def _duration(self, knots: list[np.ndarray], waypoint: Waypoint) -> int:
        """K_t: the waypoint's own, or the least that keeps the speed limits."""
        lim = self.limits
        if waypoint.ticks is not None:
            total = waypoint.ticks
        elif waypoint.path == "linear":
            start, _ = self.arm.forward(knots[0])
            distance = float(np.linalg.norm(np.subtract(waypoint.pose.position_m, start)))
            total = self.scene.ticks_for(MIN_JERK_PEAK * distance / lim.max_linear_speed_mps)
        else:
            # A joint move far out sweeps the tool faster than its joints turn: the least time
            # keeps both the joints' speed and the tool's safety envelope.
            angle = float(np.max(np.abs(knots[-1] - knots[0])))
            length = _length(self._tool_path(knots, waypoint))
            total = max(
                self.scene.ticks_for(MIN_JERK_PEAK * angle / lim.max_joint_speed_radps),
                math.ceil(
                    MIN_JERK_PEAK
                    * length
                    / self.safety.max_tcp_speed_mps
                    / self.scene.physics.time_step_s
                ),
            )
        least = max(self.scene.ticks_for(lim.min_duration_s), waypoint.min_ticks or 1)
        return max(total, least, len(knots) - 1)

    def _tool_path(self, knots: list[np.ndarray], waypoint: Waypoint) -> list[Vec3]:
        """The tool centre points the move passes through (a joint move sampled 17 times)."""
        if waypoint.path == "joint":
            samples = [knots[0] + s * (knots[-1] - knots[0]) for s in np.linspace(0, 1, 17)]
        else:
            samples = knots
        return [self.arm.forward(q)[0] for q in samples]

    def _check_safety(self, knots: list[np.ndarray], waypoint: Waypoint, ticks: int) -> None:
        """The tool path the move will follow, against the safety limits."""
        path = self._tool_path(knots, waypoint)
        obstacles = self._obstacles(path[0]) if waypoint.path == "joint" else []
        duration_s = ticks * self.scene.physics.time_step_s
        workspace = self.scene.spec.workspace
        check_motion(path, duration_s, MIN_JERK_PEAK, obstacles, workspace, self.safety)

    def _obstacles(self, start: Vec3) -> list[Box]:
        """Every brick a free move must pass above in transit: all but the one in the hand
        (near the tool centre point, or pressed by both pads however far it slid), each of
        its catalogue size."""
        obstacles = []
        for brick in range(len(self.scene.bricks)):
            center, quat = self.scene.brick_pose(brick)
            if math.dist(center, start) > HELD_DISTANCE_M and not self.scene.is_held(brick):
                size = self.scene.nominals[brick].size_m
                obstacles.append(Box(center, quat, size, id=brick))
        return obstacles

    def _move(self, knots: list[np.ndarray], waypoint: Waypoint, total: int) -> tuple[int, bool]:
        """Interpolate through the knots; a guarded move stops where its brick touches down."""
        path = np.array(knots)
        along = np.linspace(0.0, 1.0, len(knots))
        for tick in range(1, total + 1):
            s = _min_jerk(tick / total)
            target = np.array([np.interp(s, along, path[:, j]) for j in range(path.shape[1])])
            self.scene.set_arm_targets(target)
            self.scene.step()
            if waypoint.stop_on_contact is not None and (
                self.scene.support_force(waypoint.stop_on_contact) > self.limits.contact_force_n
            ):
                self.scene.set_arm_targets(self.scene.arm_joints()[0])
                return tick, True
        return total, False

    def _settle(self, target: np.ndarray) -> tuple[int, bool]:
        lim = self.limits
        limit = self.scene.ticks_for(lim.settle_max_s)
        for tick in range(limit):
            joints, speeds = self.scene.arm_joints()
            if (
                np.max(np.abs(joints - target)) < lim.joint_tolerance_rad
                and np.max(np.abs(speeds)) < lim.joint_speed_tolerance_radps
            ):
                return tick, True
            self.scene.step()
        return limit, False

    def grip(self, command: GripperCommand, opening_m: float | None = None) -> int:
        """Apply a gripper command where the arm is and wait for the fingers; returns ticks."""
        return self._actuate_gripper(command, opening_m)

    def _actuate_gripper(self, command: GripperCommand, opening_m: float | None) -> int:
        if command is GripperCommand.HOLD:
            return 0
        if command is GripperCommand.CLOSE:
            half_width = FINGER_MIN_M
        else:
            half_width = FINGER_MAX_M if opening_m is None else opening_m / 2.0
        self.scene.set_finger_target(half_width)
        ticks = self.scene.ticks_for(self.limits.gripper_s)
        self.scene.step(ticks)
        return ticks


def _min_jerk(s: float) -> float:
    """Minimum-jerk time scaling: 0 -> 0, 1 -> 1, zero velocity and acceleration at both ends."""
    return s**3 * (10.0 - 15.0 * s + 6.0 * s**2)


def _length(path: list[Vec3]) -> float:
    """The length of a polyline of tool positions."""
    return float(np.sum(np.linalg.norm(np.diff(np.asarray(path), axis=0), axis=1)))
