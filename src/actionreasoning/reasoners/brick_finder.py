"""Bricks found in colour and depth images: where each lies and how it is turned.

This is how the pixel-reading reference is to see (issue 40): nothing but the images and
the cameras they came from. A pixel is a brick's when its colour is brick red (red well
above green, and blue a fair part of red, unlike the arm's orange) and it stands above the
ground. The brick pixels split into connected regions, and a region's top (its pixels
within ``TOP_FACE_M`` of its highest) into faces where neighbours lie apart in the world.
A rectangle of the brick's footprint is laid on each face's edges by least squares, leaving
out edges at an occluder, and gives the brick's centre and yaw. :func:`merged` keeps one
find per brick of several cameras' finds.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.optimize import OptimizeResult, least_squares

from actionreasoning.world.cameras import Camera
from actionreasoning.world.geometry import Vec3

#: Brick red: red over green and over blue by these factors, blue at least this part of red
#: (the arm's orange has 4 %, the bricks 23-39 %), and red at least this bright.
RED_OVER_GREEN = 1.35
MIN_BLUE_PART = 0.12
MIN_RED = 60
#: A brick pixel stands this far above the ground (m): the depth noise of a 16-bit image is
#: 0.1 mm, a brick's lowest face 6 cm.
ABOVE_GROUND_M = 0.01
#: The top face: pixels within this of a region's highest point (m), below a brick's least
#: edge and above the depth's step across one pixel of a slanting face.
TOP_FACE_M = 0.003
#: A region smaller than this many pixels is a corner showing past an occluder, not a brick.
MIN_PIXELS = 200
#: Neighbouring pixels this far apart in the world (m) are of different faces: a pixel
#: spans at most 4 mm of a face here, two bricks side by side lie farther apart.
GAP_M = 0.01
#: Finds of two cameras this close (m, in the plane) are of one brick; bricks in a pick area
#: lie 0.24 m apart or more.
SAME_BRICK_M = 0.05


@dataclass(frozen=True)
class SeenBrick:
    """A brick's top face as seen: its centre (m), the yaw of its long side (rad, in
    (-pi/2, pi/2]), its length and width (m, the footprint fitted) and how many of its
    pixels showed."""

    top_centre_m: Vec3
    yaw_rad: float
    length_m: float
    width_m: float
    pixels: int


def find_bricks(
    rgb: np.ndarray, depth_m: np.ndarray, camera: Camera, footprints: Sequence[tuple[float, float]]
) -> list[SeenBrick]:
    """The bricks whose top faces ``camera`` sees in ``rgb`` and ``depth_m``, largest first.
    ``footprints`` are the bricks' possible (length, width) on the ground."""
    rows, cols = np.indices(depth_m.shape)
    pixels = np.column_stack([cols.ravel(), rows.ravel()]).astype(float)
    points = camera.deproject_all(pixels, depth_m.ravel().astype(float)).reshape(*depth_m.shape, 3)
    red, green, blue = (rgb[:, :, i].astype(float) for i in range(3))
    brick = (
        (red >= MIN_RED)
        & (red > RED_OVER_GREEN * green)
        & (blue >= MIN_BLUE_PART * red)
        & (points[:, :, 2] > ABOVE_GROUND_M)
    )
    regions, _ = ndimage.label(brick, structure=np.ones((3, 3), dtype=bool))
    pixel_m = float(np.median(depth_m)) / camera.fx  # ground a pixel spans, about
    seen = []
    for index, box in enumerate(ndimage.find_objects(regions), start=1):
        grown = tuple(slice(max(0, b.start - 2), b.stop + 2) for b in box)
        window, region = points[grown], regions[grown] == index
        for face in _faces(window, region):
            found = _fit(window, face, footprints, pixel_m)
            if found is not None:
                seen.append(found)
    return sorted(seen, key=lambda s: -s.pixels)


def merged(finds: Iterable[SeenBrick]) -> list[SeenBrick]:
    """One find per brick of several cameras' finds: of those within ``SAME_BRICK_M`` of
    each other, the one that showed the most pixels."""
    kept: list[SeenBrick] = []
    for find in sorted(finds, key=lambda f: -f.pixels):
        if all(math.dist(k.top_centre_m[:2], find.top_centre_m[:2]) >= SAME_BRICK_M for k in kept):
            kept.append(find)
    return kept


def _faces(points: np.ndarray, region: np.ndarray) -> list[np.ndarray]:
    """The top faces of a region: its pixels within ``TOP_FACE_M`` of its highest, split
    where neighbouring pixels lie ``GAP_M`` apart in the world (two bricks that touch in a
    slanting picture, one behind the other)."""
    heights = points[:, :, 2]
    top = region & (heights >= heights[region].max() - TOP_FACE_M)
    gap = np.zeros_like(top)
    right = np.linalg.norm(points[:, 1:] - points[:, :-1], axis=2) > GAP_M
    down = np.linalg.norm(points[1:] - points[:-1], axis=2) > GAP_M
    gap[:, :-1] |= right
    gap[:-1] |= down
    faces, count = ndimage.label(top & ~gap)
    return [faces == label for label in range(1, count + 1)]


def _fit(
    points: np.ndarray,
    top: np.ndarray,
    footprints: Sequence[tuple[float, float]],
    pixel_m: float,
) -> SeenBrick | None:
    """The brick of one top face (a mask over ``points``, an image window of world points),
    or None if too little of it shows. The top face's edges that border something
    lower (not an occluder above it) lie on the brick's sides: a rectangle of the footprint
    the visible face fits is laid on them by least squares, the face's pixels kept inside."""
    heights = points[:, :, 2]
    if top.sum() < MIN_PIXELS:
        return None
    top_z = float(heights[top].max())
    above = ndimage.binary_dilation(heights > top_z + TOP_FACE_M, np.ones((3, 3), dtype=bool))
    edge = top & ~ndimage.binary_erosion(top, np.ones((3, 3), dtype=bool)) & ~above
    edge[[0, -1], :] = edge[:, [0, -1]] = False  # the window's border is the image's, maybe
    face, sides = points[top][:, :2], points[edge][:, :2]
    centre, yaw, extent = _principal(face)
    length, width = min(
        footprints, key=lambda f: max(0.0, extent[0] - f[0]) + max(0.0, extent[1] - f[1])
    )
    # A boundary pixel's centre lies half a pixel inside the face, on average.
    half = np.array([length, width]) / 2.0 - pixel_m / 2.0
    best = min(
        (_lay(face, sides, half, centre, yaw + turn) for turn in (0.0, math.pi / 2)),
        key=lambda fit: fit.cost,
    )
    x, y, fitted_yaw = best.x
    return SeenBrick(
        top_centre_m=(float(x), float(y), float(np.mean(points[top][:, 2]))),
        yaw_rad=_half_turn(fitted_yaw),
        length_m=length,
        width_m=width,
        pixels=int(top.sum()),
    )


def _principal(face: np.ndarray) -> tuple[np.ndarray, float, tuple[float, float]]:
    """Centroid, yaw of the principal axis and the extents along it and across it."""
    centre = face.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((face - centre).T))
    axis = vectors[:, 1]
    along, across = (face - centre) @ axis, (face - centre) @ np.array([-axis[1], axis[0]])
    return centre, math.atan2(axis[1], axis[0]), (float(np.ptp(along)), float(np.ptp(across)))


def _lay(
    face: np.ndarray, sides: np.ndarray, half: np.ndarray, centre: np.ndarray, yaw: float
) -> OptimizeResult:
    """Least squares of the rectangle (x, y, yaw) of half extents ``half``: the sides'
    points on its edge, the face's points inside it."""

    def residuals(pose: np.ndarray) -> np.ndarray:
        on_edge = _signed_distance(sides, pose, half)
        outside = np.maximum(_signed_distance(face, pose, half), 0.0)
        return np.concatenate([on_edge, outside])

    return least_squares(
        residuals, np.array([centre[0], centre[1], yaw]), loss="soft_l1", f_scale=0.003
    )


def _signed_distance(points: np.ndarray, pose: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Each point's signed distance to the rectangle at ``pose`` (negative inside)."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    shifted = points - (x, y)
    local = np.abs(np.column_stack([shifted @ (c, s), shifted @ (-s, c)])) - half
    outside = np.linalg.norm(np.maximum(local, 0.0), axis=1)
    return outside + np.minimum(local.max(axis=1), 0.0)


def _half_turn(yaw: float) -> float:
    """``yaw`` in (-pi/2, pi/2]: a brick's long side has no direction."""
    return math.pi / 2 - (math.pi / 2 - yaw) % math.pi
