"""Random initial brick poses in the pick area, drawn from the trial's own generator.

Bricks are drawn one by one, uniformly over the area, and a draw too close to an earlier
brick is drawn again. Where that jams (many bricks), they go on fixed slots over the area
instead (:func:`pick_slots`): which slots, and the yaws, are drawn from the same generator.
The number of slots is the most bricks a pattern may have (:func:`pick_capacity`), so
every seed of a pattern that passed validation can be laid out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.world.geometry import Vec3, yaw_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import SceneSpec

MAX_ATTEMPTS = 10_000
#: Radii across the pick band that the slots are tried at, at every azimuth.
SLOT_RADII = 9


def sample_pick_poses(
    rng: np.random.Generator, count: int, spec: SceneSpec, size_m: Vec3 | None = None
) -> list[Pose]:
    """``count`` bricks of ``size_m`` (default: the catalogue's) lying on the ground in the
    pick area, at least the spacing apart; yaw is uniform in [-180, 180).

    Positions are uniform over the area of the annulus sector, or slots where that jams.
    """
    size = spec.brick_size_m if size_m is None else size_m
    spacing = spec.pick_spacing_m(size)
    r_min, r_max = spec.pick_radius_m
    az_min, az_max = (math.radians(a) for a in spec.pick_azimuth_deg)
    centres: list[np.ndarray] = []
    yaws: list[float] = []
    for _ in range(MAX_ATTEMPTS):
        if len(centres) == count:
            break
        radius = math.sqrt(rng.uniform(r_min**2, r_max**2))
        azimuth = rng.uniform(az_min, az_max)
        yaw = rng.uniform(-math.pi, math.pi)
        centre = np.array([radius * math.cos(azimuth), radius * math.sin(azimuth)])
        if all(np.linalg.norm(centre - c) >= spacing for c in centres):
            centres.append(centre)
            yaws.append(yaw)
    if len(centres) < count:
        slots = pick_slots(spec, size)
        if count > len(slots):
            raise ConfigError(
                f"cannot lay out {count} bricks {spacing:.3f} m apart in the pick area: "
                f"it holds {len(slots)}"
            )
        centres = [np.array(slots[i]) for i in rng.permutation(len(slots))[:count]]
        yaws = [float(yaw) for yaw in rng.uniform(-math.pi, math.pi, size=count)]
    return [
        Pose(position_m=(float(x), float(y), size[2] / 2.0), quat_xyzw=yaw_quat(yaw))
        for (x, y), yaw in zip(centres, yaws, strict=True)
    ]


def pick_slots(spec: SceneSpec, size_m: Vec3) -> list[tuple[float, float]]:
    """Brick centres (x, y) over the pick area, every two at least the spacing apart.

    A sweep over azimuth (1 degree steps) that tries, at each azimuth, radii across the band
    from its edges inwards, and keeps every point far enough from those kept before: the
    bricks come to lie in a zigzag along the two edges where the band is too narrow for two rows.
    """
    spacing = spec.pick_spacing_m(size_m)
    r_min, r_max = spec.pick_radius_m
    az_min, az_max = spec.pick_azimuth_deg
    middle = (r_min + r_max) / 2.0
    radii = sorted(
        (r_min + (r_max - r_min) * i / (SLOT_RADII - 1) for i in range(SLOT_RADII)),
        key=lambda r: -abs(r - middle),
    )
    steps = max(1, math.ceil(az_max - az_min))
    slots: list[tuple[float, float]] = []
    for j in range(steps + 1):
        azimuth = math.radians(az_min + (az_max - az_min) * j / steps)
        for radius in radii:
            slot = (radius * math.cos(azimuth), radius * math.sin(azimuth))
            if all(math.dist(slot, other) >= spacing for other in slots):
                slots.append(slot)
    return slots


def spawn_size(sizes: Sequence[Vec3], spec: SceneSpec) -> Vec3:
    """The size a pick area of bricks of ``sizes`` is laid out for: every brick is spaced as
    the one that needs the most room."""
    return max(sizes, key=spec.pick_spacing_m)


def pick_capacity(spec: SceneSpec, size_m: Vec3) -> int:
    """The most bricks of ``size_m`` the pick area holds for every seed."""
    return len(pick_slots(spec, size_m))
