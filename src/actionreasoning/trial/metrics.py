"""Per-brick placement metrics (the paper's Table I): offset, rotation errors and exact 3D IoU.

Positions and sizes are in metres, quaternions are (x, y, z, w) in the world frame and are
normalised before use, so any non-zero scaling gives the same answer.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection, QhullError
from scipy.spatial.transform import Rotation

from actionreasoning.trial.results import PlacementMetrics
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import QuatXYZW, Vec3
from actionreasoning.world.models import TargetBrick

#: The symmetries of a box with three different side lengths, in its own frame:
#: identity and the half turns about its x, y and z axes.
_BOX_SYMMETRIES = tuple(np.diag(d) for d in ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)))

#: Chebyshev radius (m) below which two boxes count as disjoint or only touching.
_MIN_DEPTH_M = 1e-9


def center_offset_cm(position_m: Vec3, target_position_m: Vec3) -> float:
    """Euclidean distance (cm) between a brick's centre and its target centre (world frame, m)."""
    return 100.0 * float(np.linalg.norm(np.subtract(position_m, target_position_m)))


def _matrix(quat_xyzw: QuatXYZW) -> np.ndarray:
    return Rotation.from_quat(np.asarray(quat_xyzw, dtype=float)).as_matrix()  # normalises


def _geodesic_deg(rot: np.ndarray, target: np.ndarray) -> float:
    cos = (np.trace(target.T @ rot) - 1.0) / 2.0
    return math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))


def rotation_error_deg(quat_xyzw: QuatXYZW, target_quat_xyzw: QuatXYZW) -> float:
    """Geodesic angle (deg, in [0, 180]) arccos((tr(R*^T R) - 1) / 2) between two orientations."""
    return _geodesic_deg(_matrix(quat_xyzw), _matrix(target_quat_xyzw))


def symmetric_rotation_error_deg(quat_xyzw: QuatXYZW, target_quat_xyzw: QuatXYZW) -> float:
    """Geodesic error (deg) up to the box's symmetries: half turns about its own axes count as 0."""
    rot, target = _matrix(quat_xyzw), _matrix(target_quat_xyzw)
    return min(_geodesic_deg(rot, target @ sym) for sym in _BOX_SYMMETRIES)


def _halfspaces(box: Box) -> np.ndarray:
    """The box as 6 rows [a, b] meaning a . x + b <= 0 (scipy's HalfspaceIntersection form)."""
    axes = _matrix(box.quat_xyzw).T  # rows: the box's own axes in the world frame
    reach = axes @ np.asarray(box.position_m, dtype=float)
    half = np.asarray(box.size_m, dtype=float) / 2.0
    return np.vstack(
        [np.column_stack([axes, -(reach + half)]), np.column_stack([-axes, reach - half])]
    )


def _intersection_volume(halfspaces: np.ndarray) -> float:
    """Volume (m^3) of the convex polyhedron {x : A x + b <= 0}; 0 if it has no interior."""
    normals, offsets = halfspaces[:, :3], halfspaces[:, 3]
    # Chebyshev centre: maximise r subject to A x + r |A_i| <= -b.
    lp = linprog(
        c=[0.0, 0.0, 0.0, -1.0],
        A_ub=np.column_stack([normals, np.linalg.norm(normals, axis=1)]),
        b_ub=-offsets,
        bounds=[(None, None)] * 3 + [(0.0, None)],
    )
    if not lp.success or lp.x is None or lp.x[3] <= _MIN_DEPTH_M:
        return 0.0
    try:
        vertices = HalfspaceIntersection(halfspaces, lp.x[:3]).intersections
        return float(ConvexHull(vertices).volume)
    except QhullError:  # degenerate (zero-volume) intersection
        return 0.0


def box_iou(a: Box, b: Box) -> float:
    """Exact intersection over union (in [0, 1]) of two oriented boxes (world frame, metres)."""
    inter = _intersection_volume(np.vstack([_halfspaces(a), _halfspaces(b)]))
    union = float(np.prod(a.size_m)) + float(np.prod(b.size_m)) - inter
    # The hull's volume of two coinciding boxes exceeds theirs by rounding (1e-14).
    return min(inter / union, 1.0)


def brick_metrics(brick: Box, target: Box) -> PlacementMetrics:
    """All four metrics of a brick against its target (world frame, metres)."""
    return PlacementMetrics(
        center_offset_cm=center_offset_cm(brick.position_m, target.position_m),
        rotation_error_deg=rotation_error_deg(brick.quat_xyzw, target.quat_xyzw),
        symmetric_rotation_error_deg=symmetric_rotation_error_deg(
            brick.quat_xyzw, target.quat_xyzw
        ),
        iou=box_iou(brick, target),
    )


def placement_of(position_m: Vec3, quat_xyzw: QuatXYZW, target: TargetBrick) -> PlacementMetrics:
    """A brick at this pose against ``target``, both of the target's size: the metrics the
    success rule judges, for the results line and for the count of bricks placed so far."""
    return brick_metrics(
        Box(position_m, quat_xyzw, target.size_m),
        Box(target.pose.position_m, target.pose.quat_xyzw, target.size_m),
    )
