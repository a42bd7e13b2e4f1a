"""Inverse kinematics of the tool centre point on a kinematic copy of the arm.

The copy lives in its own PyBullet client, so solving IK never touches the physics
client: the simulation's sequence of calls (and so its outcome) does not depend on how
often the planner asks for IK. A null-space solve whose base-joint rest angle follows the
target's azimuth is refined by damped least squares until the pose error is below tolerance.
A solution depends on its query alone, so each arm keeps the latest ones: a trial asks for
the same poses again and again (a gate checks again what a tool measured).
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np
import pybullet as p
from scipy.spatial.transform import Rotation

from actionreasoning.sim.robot_model import (
    ARM_JOINTS,
    FINGER_LEFT,
    FINGER_MAX_M,
    FINGER_RIGHT,
    TCP_LINK,
    load_robot,
)
from actionreasoning.world.geometry import (
    Joints,
    QuatXYZW,
    Vec3,
    as_quat,
    as_vec3,
    quat_yaw,
    wrap_angle,
)

#: A comfortable top-down configuration; joints 1 and 7 are set from the target.
REST_POSE_RAD = (0.0, 0.55, 0.0, -1.55, 0.0, 1.05, 0.0)
POSITION_TOLERANCE_M = 1e-4
ORIENTATION_TOLERANCE_DEG = 0.05
#: Solutions an arm keeps, the least recently asked for dropped first.
SOLUTIONS_KEPT = 4096


@dataclass(frozen=True)
class IKSolution:
    """Joint angles for a tool pose and how well they reach it."""

    joints_rad: tuple[float, ...]
    position_error_m: float
    orientation_error_deg: float
    joint_limit_margin_rad: float

    @property
    def reached(self) -> bool:
        """Whether the pose is reached within the solver's tolerances."""
        return (
            self.position_error_m <= POSITION_TOLERANCE_M
            and self.orientation_error_deg <= ORIENTATION_TOLERANCE_DEG
        )


class KinematicArm:
    """Forward and inverse kinematics of the arm's tool centre point."""

    def __init__(self) -> None:
        self._client = p.connect(p.DIRECT)
        self._robot = load_robot(self._client)
        info = [p.getJointInfo(self._robot, j, physicsClientId=self._client) for j in ARM_JOINTS]
        self.lower_rad = np.array([i[8] for i in info])
        self.upper_rad = np.array([i[9] for i in info])
        movable = [
            j
            for j in range(p.getNumJoints(self._robot, physicsClientId=self._client))
            if p.getJointInfo(self._robot, j, physicsClientId=self._client)[2] != p.JOINT_FIXED
        ]
        self._n_movable = len(movable)
        self._solved: OrderedDict[bytes, IKSolution] = OrderedDict()

    @property
    def client(self) -> int:
        """The PyBullet client of the kinematic copy (never stepped)."""
        return self._client

    @property
    def robot(self) -> int:
        """The arm's body id in :attr:`client`."""
        return self._robot

    def set_configuration(self, joints_rad: Joints, finger_half_width_m: float) -> None:
        """Put the kinematic copy in a configuration (arm joints and finger opening)."""
        self._set(joints_rad)
        for finger in (FINGER_LEFT, FINGER_RIGHT):
            p.resetJointState(
                self._robot, finger, finger_half_width_m, physicsClientId=self._client
            )

    def close(self) -> None:
        """Disconnect the kinematic copy."""
        if p.isConnected(self._client):
            p.disconnect(self._client)

    def forward(self, joints_rad: Joints) -> tuple[Vec3, QuatXYZW]:
        """Tool centre point pose (position m, quaternion xyzw) for arm joint angles."""
        self._set(joints_rad)
        state = p.getLinkState(
            self._robot, TCP_LINK, computeForwardKinematics=True, physicsClientId=self._client
        )
        return as_vec3(state[4]), as_quat(state[5])

    def default_rest(self, position_m: Vec3, quat_xyzw: QuatXYZW) -> tuple[float, ...]:
        """The rest pose with joint 1 turned towards the target and joint 7 set for its yaw.

        With the rest pose's elbow, a top-down tool's yaw is ``azimuth + pi - q7``.
        """
        azimuth = math.atan2(position_m[1], position_m[0])
        wrist = wrap_angle(azimuth + math.pi - quat_yaw(quat_xyzw))
        rest = np.clip((azimuth, *REST_POSE_RAD[1:6], wrist), self.lower_rad, self.upper_rad)
        return tuple(float(q) for q in rest)

    def solve(
        self,
        position_m: Vec3,
        quat_xyzw: QuatXYZW,
        rest_rad: Joints | None = None,
        refine_iterations: int = 30,
    ) -> IKSolution:
        """Joint angles putting the tool centre point at the pose; ``rest_rad`` seeds and biases.
        Leaves the kinematic copy in the solution's configuration."""
        key = _query_key(position_m, quat_xyzw, rest_rad, refine_iterations)
        solution = self._solved.get(key)
        if solution is not None:
            self._solved.move_to_end(key)
            self._set(solution.joints_rad)  # where solving it again would leave the copy
            return solution
        solution = self._solve(position_m, quat_xyzw, rest_rad, refine_iterations)
        self._solved[key] = solution
        if len(self._solved) > SOLUTIONS_KEPT:
            self._solved.popitem(last=False)
        return solution

    def _solve(
        self,
        position_m: Vec3,
        quat_xyzw: QuatXYZW,
        rest_rad: Joints | None,
        refine_iterations: int,
    ) -> IKSolution:
        rest = (
            list(rest_rad)
            if rest_rad is not None
            else list(self.default_rest(position_m, quat_xyzw))
        )
        finger = [FINGER_MAX_M] * (self._n_movable - len(ARM_JOINTS))
        lower = list(self.lower_rad) + [0.0] * len(finger)
        upper = list(self.upper_rad) + [0.1] * len(finger)
        ranges = [u - lo for u, lo in zip(upper, lower, strict=False)]
        self._set(rest)
        joints = self._ik(position_m, quat_xyzw, lower, upper, ranges, rest + finger)
        for _ in range(refine_iterations):
            solution = self._evaluate(joints, position_m, quat_xyzw)
            if solution.reached:
                return solution
            self._set(joints)
            joints = self._ik(position_m, quat_xyzw, None, None, None, None)
        return self._evaluate(joints, position_m, quat_xyzw)

    def _ik(self, position_m, quat_xyzw, lower, upper, ranges, rest) -> np.ndarray:
        kwargs = {}
        if rest is not None:
            kwargs = dict(lowerLimits=lower, upperLimits=upper, jointRanges=ranges, restPoses=rest)
        joints = p.calculateInverseKinematics(
            self._robot,
            TCP_LINK,
            list(position_m),
            list(quat_xyzw),
            maxNumIterations=200,
            residualThreshold=1e-7,
            physicsClientId=self._client,
            **kwargs,
        )
        return np.clip(np.array(joints[: len(ARM_JOINTS)]), self.lower_rad, self.upper_rad)

    def _evaluate(self, joints: np.ndarray, position_m: Vec3, quat_xyzw: QuatXYZW) -> IKSolution:
        reached_position, reached_quat = self.forward(joints)
        position_error = float(np.linalg.norm(np.subtract(reached_position, position_m)))
        relative = Rotation.from_quat(reached_quat).inv() * Rotation.from_quat(quat_xyzw)
        margin = float(np.min(np.minimum(joints - self.lower_rad, self.upper_rad - joints)))
        return IKSolution(
            joints_rad=tuple(float(q) for q in joints),
            position_error_m=position_error,
            orientation_error_deg=float(np.degrees(relative.magnitude())),
            joint_limit_margin_rad=margin,
        )

    def _set(self, joints_rad: Joints) -> None:
        for joint, angle in zip(ARM_JOINTS, joints_rad, strict=False):
            p.resetJointState(self._robot, joint, float(angle), physicsClientId=self._client)


def _query_key(
    position_m: Vec3, quat_xyzw: QuatXYZW, rest_rad: Joints | None, iterations: int
) -> bytes:
    """An IK query's values, bit for bit (-0.0 is not 0.0: it can turn an azimuth by 2 pi)."""
    rest = () if rest_rad is None else tuple(rest_rad)
    values = (*position_m, *quat_xyzw, rest_rad is None, iterations, *rest)
    return np.asarray(values, dtype=np.float64).tobytes()
