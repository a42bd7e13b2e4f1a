"""Free ground: where a brick can be set aside for a re-grasp."""

from __future__ import annotations

import itertools
import math

import pytest
from shapely.geometry import box

from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import yaw_quat
from actionreasoning.world.ground import GRID_STEP_M, free_spots

SIZE = (0.20, 0.095, 0.06)


def footprint(x: float, y: float, yaw: float = 0.0):
    return Box((x, y, 0.03), yaw_quat(yaw), SIZE).footprint


def test_free_ground_is_the_spot_itself() -> None:
    assert next(free_spots((0.5, 0.2), SIZE, yaw_quat(0.3), [], 0.08, 0.3)) == (0.5, 0.2)


def test_the_nearest_spot_keeps_the_margin_from_every_occupied_footprint() -> None:
    occupied = [footprint(0.5, 0.2), footprint(0.5, 0.45, 0.7)]
    spots = free_spots((0.5, 0.2), SIZE, yaw_quat(0.0), occupied, 0.08, 0.4)
    x, y = next(spots)
    brick = footprint(x, y)
    assert all(brick.distance(o) >= 0.08 for o in occupied)
    # Nearest first: the brick sits beside the occupied one, within a grid step of touching
    # the margin along one of its sides (0.095 wide + 0.08 across, 0.20 long + 0.08 along).
    assert math.hypot(x - 0.5, y - 0.2) <= 0.095 + 0.08 + 2 * GRID_STEP_M
    later = [math.hypot(sx - 0.5, sy - 0.2) for sx, sy in spots]
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(later))


def test_no_spot_when_everything_within_range_is_taken() -> None:
    occupied = [footprint(0.5, 0.2)]
    assert list(free_spots((0.5, 0.2), SIZE, yaw_quat(0.0), occupied, 0.08, 0.05)) == []


def test_a_spot_within_an_area_keeps_the_whole_footprint_inside_it() -> None:
    """Free ground at (0.5, 0.2), but the area ends at y = 0.22, inside the brick's far side
    (0.2 + 0.095 / 2): the nearest spot inside is the first grid step that brings that side
    within it, 0.22 - 0.0475 = 0.1725 rounded down to the grid, 0.16."""
    area = box(0.0, 0.0, 1.0, 0.22)
    assert not area.contains(footprint(0.5, 0.2))
    x, y = next(free_spots((0.5, 0.2), SIZE, yaw_quat(0.0), [], 0.08, 0.3, within=area))
    assert (x, y) == pytest.approx((0.5, 0.16))
    assert area.contains(footprint(x, y))
