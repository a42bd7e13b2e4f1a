"""Which bricks carry which: contact areas between level bricks, and whether a centre is held.

Shared by pattern validation (target bricks) and the support tool (measured bricks). Bricks
are boxes turned about z only; a brick rests on another when the other's top face is within
``SUPPORT_TOL_M`` of its bottom face and their footprints overlap.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from shapely import affinity
from shapely.geometry import Point, Polygon, box
from shapely.ops import unary_union

from actionreasoning.world.geometry import Vec3

SUPPORT_TOL_M = 2e-3  # how far a supporting top face may be from the bottom it carries
MIN_AREA_M2 = 1e-6  # footprint intersections smaller than this are mere touching
HULL_TOL_M = 1e-6  # a centre this close to its support hull still counts as supported


@dataclass(frozen=True)
class BrickBox:
    """A brick as a box in the world: an index, centre (m), yaw about z (rad) and size (m)."""

    index: int
    centre: Vec3
    yaw: float
    size: Vec3

    @property
    def bottom(self) -> float:
        return self.centre[2] - self.size[2] / 2.0

    @property
    def top(self) -> float:
        return self.centre[2] + self.size[2] / 2.0

    @property
    def footprint(self) -> Polygon:
        """The brick's rectangle on the ground plane."""
        half_x, half_y = self.size[0] / 2.0, self.size[1] / 2.0
        rect = box(-half_x, -half_y, half_x, half_y)
        rect = affinity.rotate(rect, self.yaw, origin=(0.0, 0.0), use_radians=True)
        return affinity.translate(rect, self.centre[0], self.centre[1])


def carriers(brick: BrickBox, others: Sequence[BrickBox]) -> list[tuple[BrickBox, Polygon]]:
    """Bricks whose top face carries ``brick``, each with its contact area."""
    level = [
        o for o in others if o.index != brick.index and abs(o.top - brick.bottom) <= SUPPORT_TOL_M
    ]
    areas = [(o, brick.footprint.intersection(o.footprint)) for o in level]
    return [(o, area) for o, area in areas if area.area > MIN_AREA_M2]


def centre_is_held(brick: BrickBox, contact_areas: Sequence[Polygon]) -> bool:
    """Whether the brick's centre lies over the convex hull of its contact areas."""
    hull = unary_union(list(contact_areas)).convex_hull
    return hull.distance(Point(brick.centre[:2])) <= HULL_TOL_M
