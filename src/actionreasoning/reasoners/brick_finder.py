"""Bricks found in colour and depth images: where each lies and how it is turned.

This is how the pixel-reading reference is to see (issue 40): nothing but the images and
the cameras they came from. A pixel is a brick's when its colour is brick red (red well
above green, and blue a fair part of red, unlike the arm's orange) and it stands above the
ground. The brick pixels split into connected regions, and a region's top (its pixels
within ``TOP_FACE_M`` of its highest) into faces where neighbours lie apart in the world.

A face's outline is where the camera sees past it: its pixels next to one that shows
something lower (the brick's side, the ground). Where an occluder above it (the arm), the
image's border or a pixel of another colour cuts the face, where it ends is not seen, and
no outline is taken there. A rectangle of each footprint is laid on the outline by least
squares, from either principal axis of the face, and a fit counts only if

- it explains the picture: the face's pixels lie inside it, the outline on its edge, and
  no pixel that sees past its plane lies inside it (a rectangle over visible ground is no
  brick), each to within ``OUTLINE_PX`` pixels;
- the outline pins it: some of the outline lies on a long side and some on a short end,
  clear of the corners, so that it can slide neither way (a face the arm or the image's
  border cuts across shows no end).

A face is a brick where the fits that count agree on one pose. Where none counts, or two
disagree (a corner whose brick could lie either way), the face is left to the other
cameras: :func:`merged` keeps one find per brick of several cameras' finds.
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
#: edge and above the depth's step across one pixel of a slanting face. A pixel lower than
#: this below it sees past the top face.
TOP_FACE_M = 0.003
#: A region smaller than this many pixels is a corner showing past an occluder, not a brick.
MIN_PIXELS = 200
#: Neighbouring pixels this far apart in the world (m) are of different faces: a pixel
#: spans at most 4 mm of a face here, two bricks side by side lie farther apart.
GAP_M = 0.01
#: Finds of two cameras this close (m, in the plane) are of one brick; bricks in a pick area
#: lie 0.24 m apart or more.
SAME_BRICK_M = 0.05
#: A fit explains a face to within this many pixels (the face's pixel spacing in the
#: world): an outline pixel's centre lies up to a pixel's diagonal (1.41) inside the side
#: it borders, the fitted side half a pixel inside, so the two lie up to 0.91 apart, and
#: the fit errs by a fraction of a pixel. (Of bench/brick_finder.py's seeds 100-109 and
#: 200-229, the right fits leave every pixel within 1.0; the one wrong fit that covers no
#: bare ground and is pinned, a quarter turned, leaves its outline 5.2 off.)
OUTLINE_PX = 1.5
#: An outline pixel this many pixels from a corner may be of either side there: a pixel's
#: diagonal (1.41) and ``OUTLINE_PX``, rounded up.
CORNER_PX = 3.0


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


@dataclass(frozen=True)
class _Face:
    """A top face in the plane (x, y, m): its pixels, its outline, where the pixels that
    see past it cross its plane, and the world length of a pixel on it."""

    pixels: np.ndarray
    outline: np.ndarray
    past: np.ndarray
    pixel_m: float


def brick_coloured(rgb: np.ndarray) -> np.ndarray:
    """Which pixels of an RGB picture are brick red (see the constants)."""
    red, green, blue = (rgb[:, :, i].astype(float) for i in range(3))
    return (red >= MIN_RED) & (red > RED_OVER_GREEN * green) & (blue >= MIN_BLUE_PART * red)


def find_bricks(
    rgb: np.ndarray, depth_m: np.ndarray, camera: Camera, footprints: Sequence[tuple[float, float]]
) -> list[SeenBrick]:
    """The bricks whose top faces ``camera`` sees in ``rgb`` and ``depth_m``, largest first.
    ``footprints`` are the bricks' possible (length, width) on the ground."""
    rows, cols = np.indices(depth_m.shape)
    pixels = np.column_stack([cols.ravel(), rows.ravel()]).astype(float)
    points = camera.deproject_all(pixels, depth_m.ravel().astype(float)).reshape(*depth_m.shape, 3)
    eye = np.asarray(camera.pose.position_m)
    rays = camera.deproject_all(pixels, np.ones(len(pixels))).reshape(*depth_m.shape, 3) - eye
    brick = brick_coloured(rgb) & (points[:, :, 2] > ABOVE_GROUND_M)
    regions, _ = ndimage.label(brick, structure=np.ones((3, 3), dtype=bool))
    pixel_m = float(np.median(depth_m)) / camera.fx  # ground a pixel spans, about
    diagonal = max(math.hypot(*footprint) for footprint in footprints)
    seen = []
    for index, box in enumerate(ndimage.find_objects(regions), start=1):
        # The window holds all the brick may cover: a footprint's diagonal around the
        # region, in pixels at its nearest.
        nearest = float(depth_m[box][regions[box] == index].min())
        reach = math.ceil(diagonal * camera.fx / nearest)
        around = tuple(slice(max(0, b.start - reach), b.stop + reach) for b in box)
        window, region = points[around], regions[around] == index
        for face in _faces(window, region):
            found = _fit(window, rays[around], eye, face, footprints, pixel_m)
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
    where neighbouring ones lie ``GAP_M`` apart in the world (two bricks that touch in a
    slanting picture, one behind the other)."""
    heights = points[:, :, 2]
    top = region & (heights >= heights[region].max() - TOP_FACE_M)
    right = np.linalg.norm(points[:, 1:] - points[:, :-1], axis=2) > GAP_M
    down = np.linalg.norm(points[1:] - points[:-1], axis=2) > GAP_M
    gap = np.zeros_like(top)
    gap[:, :-1] |= right & top[:, 1:]
    gap[:-1] |= down & top[1:]
    faces, count = ndimage.label(top & ~gap)
    return [faces == label for label in range(1, count + 1)]


def _fit(
    points: np.ndarray,
    rays: np.ndarray,
    eye: np.ndarray,
    top: np.ndarray,
    footprints: Sequence[tuple[float, float]],
    pixel_m: float,
) -> SeenBrick | None:
    """The brick of one top face (a mask over ``points``, an image window of world points
    whose pixels look along ``rays`` from ``eye``), or None if the picture does not fix
    one: see the module."""
    if top.sum() < MIN_PIXELS:
        return None
    heights = points[:, :, 2]
    top_z = float(heights[top].max())
    past = heights < top_z - TOP_FACE_M  # the camera sees past the face's plane there
    outline = top & ndimage.binary_dilation(past, np.ones((3, 3), dtype=bool))
    through = rays[past]  # where these rays cross the plane, the face is not
    crossing = eye[:2] + ((top_z - eye[2]) / through[:, 2])[:, None] * through[:, :2]
    face = _Face(points[top][:, :2], points[outline][:, :2], crossing, _spacing(points, top))
    centre, yaw = _principal(face.pixels)
    fits = []  # (cost, pose, half extents, footprint) of the fits that count
    for footprint in footprints:
        # A boundary pixel's centre lies half a pixel inside the face, on average.
        half = np.array(footprint) / 2.0 - pixel_m / 2.0
        for turn in (0.0, math.pi / 2):
            fit = _lay(face, half, centre, yaw + turn)
            if _pinned(face, fit.x, half) and _explains(face, fit.x, half):
                fits.append((float(fit.cost), fit.x, half, footprint))
    if not fits:
        return None
    _, pose, half, (length, width) = min(fits, key=lambda fit: fit[0])
    tolerance = OUTLINE_PX * face.pixel_m
    for _, other, other_half, _ in fits:  # another pose that counts: the brick could lie either way
        if np.abs(_signed_distance(_corners(other, other_half), pose, half)).max() > tolerance:
            return None
    x, y, fitted_yaw = pose
    return SeenBrick(
        top_centre_m=(float(x), float(y), float(np.mean(points[top][:, 2]))),
        yaw_rad=_half_turn(fitted_yaw),
        length_m=length,
        width_m=width,
        pixels=int(top.sum()),
    )


def _spacing(points: np.ndarray, top: np.ndarray) -> float:
    """A pixel's length on a face (m): the larger of the median distances between its
    neighbouring pixels along the rows and down the columns (0 if it has none, a face that
    then explains nothing)."""
    right = np.linalg.norm(points[:, 1:] - points[:, :-1], axis=2)[top[:, 1:] & top[:, :-1]]
    down = np.linalg.norm(points[1:] - points[:-1], axis=2)[top[1:] & top[:-1]]
    return max((float(np.median(d)) for d in (right, down) if d.size), default=0.0)


def _principal(pixels: np.ndarray) -> tuple[np.ndarray, float]:
    """Centroid and yaw of the principal axis."""
    centre = pixels.mean(axis=0)
    _, vectors = np.linalg.eigh(np.cov((pixels - centre).T))
    axis = vectors[:, 1]
    return centre, math.atan2(axis[1], axis[0])


def _lay(face: _Face, half: np.ndarray, centre: np.ndarray, yaw: float) -> OptimizeResult:
    """Least squares of the rectangle (x, y, yaw) of half extents ``half``: the outline on
    its edge, the face's pixels inside it."""

    def residuals(pose: np.ndarray) -> np.ndarray:
        on_edge = _signed_distance(face.outline, pose, half)
        outside = np.maximum(_signed_distance(face.pixels, pose, half), 0.0)
        return np.concatenate([on_edge, outside])

    return least_squares(
        residuals, np.array([centre[0], centre[1], yaw]), loss="soft_l1", f_scale=0.003
    )


def _pinned(face: _Face, pose: np.ndarray, half: np.ndarray) -> bool:
    """Whether some of the outline lies on a long side and some on a short end of the
    rectangle at ``pose``, each ``CORNER_PX`` pixels or more from the other sides."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    shifted = face.outline - (x, y)
    along, across = np.abs(shifted @ (c, s)), np.abs(shifted @ (-s, c))
    near, clear = OUTLINE_PX * face.pixel_m, CORNER_PX * face.pixel_m
    on_long = (np.abs(across - half[1]) <= near) & (along <= half[0] - clear)
    on_end = (np.abs(along - half[0]) <= near) & (across <= half[1] - clear)
    return bool(on_long.any() and on_end.any())


def _explains(face: _Face, pose: np.ndarray, half: np.ndarray) -> bool:
    """Whether the rectangle at ``pose`` explains the face to within ``OUTLINE_PX``
    pixels: its pixels inside, its outline on the edge, nothing seen past it inside."""
    tolerance = OUTLINE_PX * face.pixel_m
    return bool(
        _signed_distance(face.pixels, pose, half).max() <= tolerance
        and np.abs(_signed_distance(face.outline, pose, half)).max() <= tolerance
        and not (_signed_distance(face.past, pose, half) < -tolerance).any()
    )


def _corners(pose: np.ndarray, half: np.ndarray) -> np.ndarray:
    """The four corners of the rectangle at ``pose`` (4 x 2)."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    local = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]]) * half
    return local @ np.array([[c, s], [-s, c]]) + (x, y)


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
