"""The one box type: a brick, a target or an obstacle as an oriented box in the world frame."""

from __future__ import annotations

from dataclasses import dataclass

from shapely import affinity
from shapely.geometry import Polygon, box

from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw


@dataclass(frozen=True)
class Box:
    """An oriented box: centre (m), orientation (x, y, z, w), edge lengths (m) along its own
    axes, and the id of the brick or target it stands for, if any.

    ``bottom_m``, ``top_m`` and ``footprint`` take the box as level (turned about z only).
    """

    position_m: Vec3
    quat_xyzw: QuatXYZW
    size_m: Vec3
    id: int | None = None

    @property
    def named_id(self) -> int:
        """The id of a box that stands for a brick or a target."""
        if self.id is None:
            raise ValueError("this box stands for no brick or target")
        return self.id

    @property
    def bottom_m(self) -> float:
        return self.position_m[2] - self.size_m[2] / 2.0

    @property
    def top_m(self) -> float:
        return self.position_m[2] + self.size_m[2] / 2.0

    @property
    def footprint(self) -> Polygon:
        """The box's rectangle on the ground plane, at its yaw."""
        half_x, half_y = self.size_m[0] / 2.0, self.size_m[1] / 2.0
        rect = box(-half_x, -half_y, half_x, half_y)
        rect = affinity.rotate(rect, quat_yaw(self.quat_xyzw), origin=(0.0, 0.0), use_radians=True)
        return affinity.translate(rect, self.position_m[0], self.position_m[1])
