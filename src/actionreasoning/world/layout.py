"""Random initial brick poses in the pick area, drawn from the trial's own generator."""

from __future__ import annotations

import math

import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.world.geometry import yaw_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.scene_spec import SceneSpec

MAX_ATTEMPTS = 10_000


def sample_pick_poses(rng: np.random.Generator, count: int, spec: SceneSpec) -> list[Pose]:
    """``count`` brick poses lying on the ground in the pick area, at least the spacing apart.

    Positions are uniform over the area of the annulus sector; yaw is uniform in [-180, 180).
    """
    r_min, r_max = spec.pick_radius_m
    az_min, az_max = (math.radians(a) for a in spec.pick_azimuth_deg)
    half_height = spec.brick_size_m[2] / 2.0
    centres: list[np.ndarray] = []
    poses: list[Pose] = []
    for _ in range(MAX_ATTEMPTS):
        if len(poses) == count:
            return poses
        radius = math.sqrt(rng.uniform(r_min**2, r_max**2))
        azimuth = rng.uniform(az_min, az_max)
        yaw = rng.uniform(-math.pi, math.pi)
        centre = np.array([radius * math.cos(azimuth), radius * math.sin(azimuth)])
        if all(np.linalg.norm(centre - c) >= spec.pick_min_spacing_m for c in centres):
            centres.append(centre)
            poses.append(
                Pose(position_m=(*map(float, centre), half_height), quat_xyzw=yaw_quat(yaw))
            )
    raise ConfigError(
        f"cannot lay out {count} bricks {spec.pick_min_spacing_m} m apart in the pick area "
        f"(radius {r_min}-{r_max} m, azimuth {spec.pick_azimuth_deg[0]} to "
        f"{spec.pick_azimuth_deg[1]} deg)"
    )
