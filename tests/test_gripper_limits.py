"""The gripper's opening, one constant (``GRIPPER_GAP_M``), is the finger joints' limits in
the URDF PyBullet loads (each finger moves half the gap)."""

from __future__ import annotations

import pybullet as p
import pytest

from actionreasoning.sim.robot_model import FINGER_LEFT, FINGER_RIGHT, load_robot
from actionreasoning.world.scene_spec import GRIPPER_GAP_M


def test_the_urdfs_finger_limits_are_half_the_gripper_gap() -> None:
    cid = p.connect(p.DIRECT)
    try:
        robot = load_robot(cid)
        for finger in (FINGER_LEFT, FINGER_RIGHT):
            info = p.getJointInfo(robot, finger, physicsClientId=cid)
            assert info[2] == p.JOINT_PRISMATIC, info[1]
            lower, upper = info[8], info[9]
            assert (2 * lower, 2 * upper) == pytest.approx(GRIPPER_GAP_M), info[1]
    finally:
        p.disconnect(cid)
