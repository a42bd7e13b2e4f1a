"""The arm-plus-gripper model: pybullet_data's KUKA LBR iiwa with our parallel-jaw gripper.

The gripper is appended to the arm's URDF as ordinary links, so arm and gripper are one
rigid multibody (no soft constraint between flange and palm) and IK can target the tool
centre point directly.
"""

from __future__ import annotations

import re
import tempfile
from importlib import resources
from pathlib import Path

import pybullet as p
import pybullet_data

from actionreasoning.world.scene_spec import FINGERTIPS_BEYOND_TCP_M, GRIPPER_GAP_M

ARM_JOINTS: tuple[int, ...] = tuple(range(7))
FINGER_LEFT = 8
FINGER_RIGHT = 9
TCP_LINK = 10
FINGER_MIN_M = GRIPPER_GAP_M[0] / 2.0
FINGER_MAX_M = GRIPPER_GAP_M[1] / 2.0
FINGER_PAD_BELOW_TCP_M = FINGERTIPS_BEYOND_TCP_M


def load_robot(client: int) -> int:
    """Load the arm+gripper into PyBullet ``client`` with a fixed base at the origin."""
    arm_dir = Path(pybullet_data.getDataPath()) / "kuka_iiwa"
    arm = (arm_dir / "model.urdf").read_text()
    arm = re.sub(r'filename="meshes/', f'filename="{arm_dir.as_posix()}/meshes/', arm)
    gripper = resources.files("actionreasoning.sim").joinpath("assets/gripper.urdf.xml").read_text()
    with tempfile.TemporaryDirectory(prefix="actionreasoning-") as tmpdir:
        path = Path(tmpdir) / "iiwa_gripper.urdf"
        path.write_text(arm.replace("</robot>", gripper + "\n</robot>"))
        return p.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
