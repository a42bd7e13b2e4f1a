"""Which bricks carry which: contact areas between level bricks, and whether a centre is held.

Shared by pattern validation (target bricks) and the support tool (measured bricks). Bricks
are boxes turned about z only; a brick rests on another when the other's top face is within
``SUPPORT_TOL_M`` of its bottom face and their footprints overlap.
"""

from __future__ import annotations

from collections.abc import Sequence

from shapely.geometry import Point
from shapely.geometry.base import BaseGeometry
from shapely.ops import unary_union

from actionreasoning.world.boxes import Box

SUPPORT_TOL_M = 2e-3  # how far a supporting top face may be from the bottom it carries
MIN_AREA_M2 = 1e-6  # footprint intersections smaller than this are mere touching
HULL_TOL_M = 1e-6  # a centre this close to its support hull still counts as supported


def carriers(brick: Box, others: Sequence[Box]) -> list[tuple[Box, BaseGeometry]]:
    """Bricks whose top face carries ``brick``, each with its contact area."""
    level = [
        o for o in others if o.id != brick.id and abs(o.top_m - brick.bottom_m) <= SUPPORT_TOL_M
    ]
    areas = [(o, brick.footprint.intersection(o.footprint)) for o in level]
    return [(o, area) for o, area in areas if area.area > MIN_AREA_M2]


def centre_is_held(brick: Box, contact_areas: Sequence[BaseGeometry]) -> bool:
    """Whether the brick's centre lies over the convex hull of its contact areas."""
    hull = unary_union(list(contact_areas)).convex_hull
    return hull.distance(Point(brick.position_m[:2])) <= HULL_TOL_M
