"""The arm's inverse kinematics: a pose asked for again gets the solution a fresh arm finds,
and leaves the kinematic copy where solving it leaves it."""

from __future__ import annotations

import pybullet as p

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.robot_model import ARM_JOINTS
from actionreasoning.world.geometry import top_down_quat


def configuration(arm: KinematicArm) -> tuple[float, ...]:
    return tuple(p.getJointState(arm.robot, j, physicsClientId=arm.client)[0] for j in ARM_JOINTS)


def test_a_pose_solved_again_is_solved_as_by_a_fresh_arm(arm: KinematicArm) -> None:
    pose, elsewhere = ((0.5, 0.1, 0.2), top_down_quat(0.3)), ((0.4, -0.3, 0.3), top_down_quat(1.0))
    first = arm.solve(*pose)
    assert configuration(arm) == first.joints_rad
    arm.solve(*elsewhere)
    again = arm.solve(*pose)
    assert configuration(arm) == again.joints_rad
    fresh = KinematicArm()
    try:
        assert again == first == fresh.solve(*pose)
        seeded = fresh.solve(*pose, rest_rad=arm.solve(*elsewhere).joints_rad)
        assert arm.solve(*pose, rest_rad=arm.solve(*elsewhere).joints_rad) == seeded
    finally:
        fresh.close()
