"""Random initial brick poses in the pick area, drawn from the trial's own generator."""

from __future__ import annotations

import math

import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.world.geometry import Vec3, yaw_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import SceneSpec

MAX_ATTEMPTS = 10_000


def sample_pick_poses(
    rng: np.random.Generator, count: int, spec: SceneSpec, size_m: Vec3 | None = None
) -> list[Pose]:
    """``count`` bricks of ``size_m`` (default: the catalogue's) lying on the ground in the
    pick area, at least the spacing apart; yaw is uniform in [-180, 180).

    Positions are uniform over the area of the annulus sector.
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
        raise ConfigError(
            f"cannot lay out {count} bricks {spacing:.3f} m apart in the pick area "
            f"(radius {r_min}-{r_max} m, azimuth {spec.pick_azimuth_deg[0]} to "
            f"{spec.pick_azimuth_deg[1]} deg)"
        )
    return [
        Pose(position_m=(float(x), float(y), size[2] / 2.0), quat_xyzw=yaw_quat(yaw))
        for (x, y), yaw in zip(centres, yaws, strict=True)
    ]
