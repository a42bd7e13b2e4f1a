"""The image tier's cameras: a pixel and its depth give the world point by the pinhole
formula, computed here by hand, and a rendered depth image agrees with the scene."""

from __future__ import annotations

import math

import numpy as np
import pytest

from actionreasoning.world.cameras import OVERVIEW, TOP_DOWN, Camera


def straight_down() -> Camera:
    """2 m above the origin looking down, 101 x 101 pixels over 90 deg: focal length
    50.5 / tan(45 deg) = 50.5 pixels, principal point (50, 50), image top towards +y."""
    up = (0.0, 1.0, 0.0)
    return Camera.looking_at("down", (0.0, 0.0, 2.0), (0.0, 0.0, 0.0), up, 90.0, 101, 101)


def test_intrinsics_by_hand() -> None:
    camera = straight_down()
    assert (camera.fx, camera.fy, camera.cx, camera.cy) == pytest.approx((50.5, 50.5, 50.0, 50.0))


@pytest.mark.parametrize(
    ("pixel", "depth", "world"),
    [
        ((50.0, 50.0), 2.0, (0.0, 0.0, 0.0)),  # the principal point, on the ground
        # 50 columns right: x = 50 / 50.5 * 2 m to the right, which is world +x
        ((100.0, 50.0), 2.0, (100.0 / 50.5, 0.0, 0.0)),
        # 50 rows up: y = -50 / 50.5 * 2 m in the camera frame, which is world +y
        ((50.0, 0.0), 2.0, (0.0, 100.0 / 50.5, 0.0)),
        # a point 0.5 m above the ground, 10 columns left and 20 rows down
        ((40.0, 70.0), 1.5, (-10 / 50.5 * 1.5, -20 / 50.5 * 1.5, 0.5)),
    ],
)
def test_deprojection_by_hand(
    pixel: tuple[float, float], depth: float, world: tuple[float, float, float]
) -> None:
    assert straight_down().deproject(*pixel, depth) == pytest.approx(world, abs=1e-12)


@pytest.mark.parametrize("camera", [TOP_DOWN, OVERVIEW], ids=lambda c: c.name)
def test_projection_undoes_deprojection(camera: Camera) -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        u, v = rng.uniform(0, camera.width), rng.uniform(0, camera.height)
        depth = rng.uniform(0.5, 3.0)
        assert camera.project(camera.deproject(u, v, depth)) == pytest.approx((u, v, depth))


def test_the_top_down_camera_sees_the_pick_and_build_areas() -> None:
    """Its image covers the areas' corners: the pick annulus (radius 0.44-0.72 m, azimuth
    -150 to -15 deg) and the build area (radius 0.58 m at 40 deg, a brick either side)."""
    corners = [
        (r * math.cos(math.radians(a)), r * math.sin(math.radians(a)), 0.0)
        for r in (0.44, 0.72)
        for a in (-150.0, -90.0, -15.0)
    ] + [(0.58 * math.cos(math.radians(40)) + dx, 0.58 * math.sin(math.radians(40)) + dy, 0.0)
         for dx in (-0.15, 0.15) for dy in (-0.15, 0.15)]  # fmt: skip
    for corner in corners:
        u, v, _ = TOP_DOWN.project(corner)
        assert 0 <= u < TOP_DOWN.width and 0 <= v < TOP_DOWN.height, corner


def test_the_view_of_a_plane_by_hand() -> None:
    """Straight down from 2 m over 90 deg: the image's outer corners, half a pixel past the
    outer pixels' centres, are 50.5 pixels from the principal point, one focal length, so
    the plane z = h shows (2 - h) m either side; its top edge lies towards +y."""
    camera = straight_down()
    for height in (0.0, 0.5):
        half = 2.0 - height
        corners = [(-half, half), (half, half), (half, -half), (-half, -half)]
        np.testing.assert_allclose(camera.view_at_height(height), corners, atol=1e-12)


def test_a_plane_seen_up_to_the_horizon_has_no_bounded_view() -> None:
    up = (0.0, 0.0, 1.0)
    level = Camera.looking_at("level", (0.0, 0.0, 1.0), (1.0, 0.0, 1.0), up, 60.0, 64, 48)
    with pytest.raises(ValueError, match="level"):
        level.view_at_height(0.0)
    with pytest.raises(ValueError, match="down"):
        straight_down().view_at_height(2.5)  # above the camera, behind it
