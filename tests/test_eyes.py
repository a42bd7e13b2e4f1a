"""The image tier's pictures: a depth image deprojects onto the scene it shows, and the
pixel-reading reference's brick finder places every brick of a layout from the pictures
alone, the arm waiting over the pick area as it does before each pick."""

from __future__ import annotations

import math

import numpy as np
import pytest

from actionreasoning.reasoners.brick_finder import SeenBrick, find_bricks, merged
from actionreasoning.sim.eyes import capture
from actionreasoning.sim.scene import Scene
from actionreasoning.world.cameras import PICK_SIDE, TOP_DOWN
from actionreasoning.world.geometry import quat_yaw

FOOTPRINT = (0.2, 0.095)


def test_the_ground_deprojects_to_z_zero_and_rendering_changes_nothing(scene: Scene) -> None:
    before = [scene.brick_pose(i) for i in range(len(scene.bricks))]
    shot = capture(scene.client, TOP_DOWN)
    assert [scene.brick_pose(i) for i in range(len(scene.bricks))] == before
    assert shot.rgb.shape == (640, 640, 3) and shot.depth_m.shape == (640, 640)
    corner = TOP_DOWN.deproject(5.0, 5.0, float(shot.depth_m[5, 5]))  # far from the arm
    assert corner[2] == pytest.approx(0.0, abs=1e-3)


def seen_by_both(scene: Scene) -> list[SeenBrick]:
    """The bricks the two depth cameras find, one find per brick."""
    shots = [capture(scene.client, camera) for camera in (TOP_DOWN, PICK_SIDE)]
    return merged(
        find
        for shot in shots
        for find in find_bricks(shot.rgb, shot.depth_m, shot.camera, [FOOTPRINT])
    )


def test_every_brick_of_a_layout_is_found_where_it_lies(scene: Scene) -> None:
    seen = seen_by_both(scene)
    assert len(seen) == len(scene.bricks)
    for brick in range(len(scene.bricks)):
        position, quat = scene.brick_pose(brick)
        found = min(seen, key=lambda s: math.dist(s.top_centre_m[:2], position[:2]))
        assert math.dist(found.top_centre_m[:2], position[:2]) < 0.005
        assert found.top_centre_m[2] == pytest.approx(position[2] + 0.03, abs=0.002)
        turn = (found.yaw_rad - quat_yaw(quat) + math.pi / 2) % math.pi - math.pi / 2
        assert abs(math.degrees(turn)) < 1.0
        assert (found.length_m, found.width_m) == FOOTPRINT


def test_a_picture_without_bricks_finds_none(scene: Scene) -> None:
    shot = capture(scene.client, TOP_DOWN)
    grey = np.full_like(shot.rgb, 128)
    assert find_bricks(grey, shot.depth_m, TOP_DOWN, [FOOTPRINT]) == []
