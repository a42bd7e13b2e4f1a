"""Shared fixtures: a real PyBullet scene (DIRECT mode) with the default layout."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.eval.trial import READY_POSE
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import top_down_quat
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import SceneSpec

#: Three bricks: two side by side and one on top; a short end-to-end build.
SMALL_PATTERN = {
    "name": "small",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [
        {"position": [-0.125, 0.0, 0.03], "yaw_deg": 0},
        {"position": [0.125, 0.0, 0.03], "yaw_deg": 0},
        {"position": [0.0, 0.0, 0.09], "yaw_deg": 0},
    ],
}


@pytest.fixture
def small_pattern(tmp_path: Path) -> Path:
    """The small pattern written to a JSON file."""
    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return path


@pytest.fixture
def arm() -> Iterator[KinematicArm]:
    arm = KinematicArm()
    yield arm
    arm.close()


@pytest.fixture
def scene(arm: KinematicArm) -> Iterator[Scene]:
    spec = SceneSpec()
    ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
    scene = Scene(spec, sample_pick_poses(np.random.default_rng(7), 6, spec), ready)
    yield scene
    scene.close()


def at(x: float, y: float, z: float, quat: tuple[float, ...]) -> Pose:
    """A pose at (x, y, z) with orientation ``quat``."""
    return Pose(position_m=(x, y, z), quat_xyzw=quat)


def pick_up(controller: WaypointController, brick: int, yaw: float, lift_to_m: float) -> None:
    """Grasp ``brick`` top-down at gripper yaw ``yaw`` (rad) and lift it to ``lift_to_m``."""
    (x, y, z), _ = controller.scene.brick_pose(brick)
    quat = top_down_quat(yaw)
    for waypoint in (
        Waypoint(
            pose=Pose(position_m=(x, y, z + 0.12), quat_xyzw=quat), gripper=GripperCommand.OPEN
        ),
        Waypoint(pose=Pose(position_m=(x, y, z), quat_xyzw=quat), path="linear"),
        Waypoint(pose=Pose(position_m=(x, y, z), quat_xyzw=quat), gripper=GripperCommand.CLOSE),
        Waypoint(pose=Pose(position_m=(x, y, lift_to_m), quat_xyzw=quat), path="linear"),
    ):
        controller.execute(waypoint)
