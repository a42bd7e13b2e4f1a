"""Free ground: spots where a brick can be set down on the ground, clear of everything else."""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

from shapely.geometry import Polygon
from shapely.ops import unary_union
from shapely.prepared import prep

from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import QuatXYZW, Vec3

#: Spacing of the candidate spots.
GRID_STEP_M = 0.02


def free_spots(
    near: tuple[float, float],
    size: Vec3,
    quat_xyzw: QuatXYZW,
    occupied: Sequence[Polygon],
    margin_m: float,
    max_distance_m: float,
    within: Polygon | None = None,
) -> Iterator[tuple[float, float]]:
    """Spots for a brick of ``size`` lying at the yaw of ``quat_xyzw``, nearest ``near``
    first, whose footprint keeps ``margin_m`` from every ``occupied`` footprint and, given
    ``within``, lies wholly inside it, within ``max_distance_m``."""
    blocked = prep(unary_union(list(occupied)).buffer(margin_m)) if occupied else None
    inside = prep(within) if within is not None else None
    reach = int(max_distance_m / GRID_STEP_M)
    steps = [k * GRID_STEP_M for k in range(-reach, reach + 1)]
    offsets = sorted(((dx, dy) for dx in steps for dy in steps), key=lambda d: (math.hypot(*d), d))
    for dx, dy in offsets:
        if math.hypot(dx, dy) > max_distance_m:
            return
        x, y = near[0] + dx, near[1] + dy
        footprint = Box((x, y, size[2] / 2.0), quat_xyzw, size).footprint
        if (blocked is None or not blocked.intersects(footprint)) and (
            inside is None or inside.contains(footprint)
        ):
            yield x, y
