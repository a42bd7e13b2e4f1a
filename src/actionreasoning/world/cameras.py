"""Pinhole cameras of the image tier: intrinsics and pose, and the two maps between a world
point and a pixel with its depth.

Conventions are OpenCV's: pixel (u, v) counts columns rightwards and rows downwards from the
top-left pixel's centre at (0, 0); the camera frame has x to the right of the image, y down
it and z along the optical axis; ``depth`` is a point's z in that frame (m), which is what
a depth image holds. ``pose`` is the camera frame in the world: a point p_c in the camera
frame is R p_c + t in the world. So a pixel and its depth give a world point::

    p_c = ((u - cx) / fx * depth, (v - cy) / fy * depth, depth)
    p_w = R p_c + t
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, PositiveFloat, PositiveInt
from scipy.spatial.transform import Rotation

from actionreasoning.world.geometry import Vec3, as_vec3
from actionreasoning.world.models import Pose


class Camera(BaseModel):
    """A named pinhole camera: image size, focal lengths and principal point (pixels), and
    its pose in the world."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: str
    width: PositiveInt
    height: PositiveInt
    fx: PositiveFloat = Field(description="Focal length along u (pixels).")
    fy: PositiveFloat = Field(description="Focal length along v (pixels).")
    cx: float = Field(description="Principal point, column (pixels).")
    cy: float = Field(description="Principal point, row (pixels).")
    pose: Pose = Field(description="The camera frame (x right, y down, z forward) in the world.")

    @classmethod
    def looking_at(
        cls,
        name: str,
        eye_m: Vec3,
        target_m: Vec3,
        up: Vec3,
        vertical_fov_deg: float,
        width: int,
        height: int,
    ) -> Camera:
        """A camera at ``eye_m`` looking at ``target_m``, the image's top towards ``up``,
        with square pixels and the principal point at the image's centre."""
        forward = np.subtract(target_m, eye_m)
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, up)
        if np.linalg.norm(right) < 1e-9:
            raise ValueError(f"camera {name!r}: up {up} is along the line of sight")
        right /= np.linalg.norm(right)
        down = np.cross(forward, right)
        rotation = Rotation.from_matrix(np.column_stack([right, down, forward]))
        focal = height / 2.0 / math.tan(math.radians(vertical_fov_deg) / 2.0)
        return cls(
            name=name,
            width=width,
            height=height,
            fx=focal,
            fy=focal,
            cx=(width - 1) / 2.0,
            cy=(height - 1) / 2.0,
            pose=Pose(position_m=as_vec3(eye_m), quat_xyzw=tuple(rotation.as_quat())),
        )

    @property
    def rotation(self) -> Rotation:
        """The camera frame's orientation in the world."""
        return Rotation.from_quat(self.pose.quat_xyzw)

    def deproject(self, u: float, v: float, depth_m: float) -> Vec3:
        """The world point seen at pixel (u, v) at ``depth_m`` along the optical axis."""
        return as_vec3(self.deproject_all(np.array([[u, v]]), np.array([depth_m]))[0])

    def deproject_all(self, pixels: np.ndarray, depths_m: np.ndarray) -> np.ndarray:
        """World points (n x 3) of ``pixels`` (n x 2: u, v) at ``depths_m`` (n)."""
        u, v = pixels[:, 0], pixels[:, 1]
        in_camera = np.column_stack(
            [(u - self.cx) / self.fx * depths_m, (v - self.cy) / self.fy * depths_m, depths_m]
        )
        return self.rotation.apply(in_camera) + np.asarray(self.pose.position_m)

    def view_at_height(self, height_m: float) -> tuple[tuple[float, float], ...]:
        """The corners (x, y) of the part of the horizontal plane at ``height_m`` that the
        image shows: where the rays through the image's four outer corners meet the plane.
        A camera whose image reaches the horizon shows no bounded part of it: ValueError."""
        right, bottom = self.width - 0.5, self.height - 0.5
        corners = np.array([[-0.5, -0.5], [right, -0.5], [right, bottom], [-0.5, bottom]])
        eye = np.asarray(self.pose.position_m)
        rays = self.deproject_all(corners, np.ones(4)) - eye  # one unit of depth along each
        drop = height_m - eye[2]
        if np.any(rays[:, 2] * drop <= 0.0):
            raise ValueError(f"camera {self.name!r} sees past the plane z = {height_m} m")
        points = eye + rays * (drop / rays[:, 2])[:, None]
        return tuple((float(x), float(y)) for x, y, _ in points)

    def project(self, point_m: Vec3) -> tuple[float, float, float]:
        """Pixel (u, v) where ``point_m`` is seen, and its depth (m)."""
        x, y, z = self.rotation.inv().apply(np.subtract(point_m, self.pose.position_m))
        return (self.fx * x / z + self.cx, self.fy * y / z + self.cy, float(z))


#: The image tier's cameras, fixed in the world. ``top_down`` looks straight down from 1.8 m
#: over the middle of the pick and build areas (both lie within 0.75 m of that point in x
#: and y): 45.2 deg of view on 640 pixels, 2.3 mm of ground a pixel, the image's top
#: towards world +y and its right towards +x; its depth image goes with it. ``overview``
#: sees the whole workspace at a slant from behind the arm.
TOP_DOWN = Camera.looking_at(
    "top_down",
    eye_m=(0.05, -0.1, 1.8),
    target_m=(0.05, -0.1, 0.0),
    up=(0.0, 1.0, 0.0),
    vertical_fov_deg=2 * math.degrees(math.atan(0.75 / 1.8)),
    width=640,
    height=640,
)
OVERVIEW = Camera.looking_at(
    "overview",
    eye_m=(-1.1, -0.1, 1.4),
    target_m=(0.2, -0.1, 0.0),
    up=(0.0, 0.0, 1.0),
    vertical_fov_deg=50.0,
    width=480,
    height=360,
)
#: The pick area from outside it, at a slant, with depth: the arm, waiting behind the
#: bricks, hides none of them from here as it hides some from above.
PICK_SIDE = Camera.looking_at(
    "pick_side",
    eye_m=(0.1, -1.6, 1.1),
    target_m=(0.05, -0.35, 0.0),
    up=(0.0, 0.0, 1.0),
    vertical_fov_deg=50.0,
    width=640,
    height=480,
)
