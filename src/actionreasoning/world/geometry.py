"""Small rigid-body helpers shared by every layer (quaternions are always x, y, z, w)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

Vec3 = tuple[float, float, float]
QuatXYZW = tuple[float, float, float, float]
#: Joint angles (rad), from a model, a controller or the simulator: a sequence or an array.
Joints = Sequence[float] | np.ndarray

#: How far from 1 a quaternion's norm may be and still be normalised rather than refused.
QUAT_NORM_TOLERANCE = 1e-3
#: The farthest a pose asked of a tool, or a corner of the workspace box, may be from the
#: arm's base along any axis: far beyond its reach (the tools report that), far below the
#: numbers that hang its IK (1e308).
MAX_COORDINATE_M = 100.0

#: A gripper pointing straight down: its z axis along world -z (a half turn about x).
TOP_DOWN = Rotation.from_euler("x", math.pi)


def as_vec3(values: Iterable[float]) -> Vec3:
    """Three numbers (a list, an array, a simulator's tuple) as a :data:`Vec3`."""
    x, y, z = (float(v) for v in values)
    return (x, y, z)


def as_quat(values: Iterable[float]) -> QuatXYZW:
    """Four numbers, x, y, z, w, as a :data:`QuatXYZW`."""
    x, y, z, w = (float(v) for v in values)
    return (x, y, z, w)


def yaw_quat(yaw_rad: float) -> QuatXYZW:
    """Quaternion (x, y, z, w) of a rotation by ``yaw_rad`` about the world z axis."""
    return as_quat(Rotation.from_euler("z", yaw_rad).as_quat())


def quat_yaw(quat_xyzw: QuatXYZW) -> float:
    """Yaw (rad) of a rotation: the heading of its x axis projected on the ground plane."""
    x_axis = Rotation.from_quat(quat_xyzw).apply([1.0, 0.0, 0.0])
    return math.atan2(x_axis[1], x_axis[0])


def top_down_quat(yaw_rad: float) -> QuatXYZW:
    """Orientation of a downward-pointing gripper turned by ``yaw_rad`` about world z."""
    return as_quat((Rotation.from_euler("z", yaw_rad) * TOP_DOWN).as_quat())


def tilt_deg(quat_xyzw: QuatXYZW) -> float:
    """Angle (deg) between a body's z axis and world up, either way up (0 to 90)."""
    up = Rotation.from_quat(quat_xyzw).apply([0.0, 0.0, 1.0])
    return math.degrees(math.acos(float(np.clip(abs(up[2]), 0.0, 1.0))))


def axis_angle_deg(a_xyzw: QuatXYZW, b_xyzw: QuatXYZW) -> float:
    """Angle (deg) between the z axes of two orientations, either way up (0 to 90)."""
    za = Rotation.from_quat(a_xyzw).apply([0.0, 0.0, 1.0])
    zb = Rotation.from_quat(b_xyzw).apply([0.0, 0.0, 1.0])
    return math.degrees(math.acos(float(np.clip(abs(np.dot(za, zb)), 0.0, 1.0))))


def rotation_deg(a_xyzw: QuatXYZW, b_xyzw: QuatXYZW) -> float:
    """Angle (deg) of the rotation that turns orientation ``a`` into ``b``."""
    turn = Rotation.from_quat(a_xyzw).inv() * Rotation.from_quat(b_xyzw)
    return math.degrees(float(turn.magnitude()))


def wrap_angle(angle_rad: float) -> float:
    """Wrap an angle into [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def round_floats(value: Any, digits: int) -> Any:
    """``value`` with every float in it (in lists, tuples and dicts too) rounded to
    ``digits`` decimals; -0.0 becomes 0.0."""
    if isinstance(value, float):
        return round(value, digits) + 0.0
    if isinstance(value, list | tuple):
        return [round_floats(v, digits) for v in value]
    if isinstance(value, dict):
        return {k: round_floats(v, digits) for k, v in value.items()}
    return value
