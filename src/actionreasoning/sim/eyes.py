"""What the image tier's cameras see: colour and metric depth of a :class:`Camera`, rendered
headless by PyBullet's TinyRenderer. Rendering reads the scene and never steps it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from actionreasoning.world.cameras import Camera
from actionreasoning.world.pictures import SHOWN, Picture, PictureKind, colour_png, depth_png

#: The depth buffer's clipping planes (m): nearer than any camera is to a brick, beyond the
#: farthest ground it sees.
NEAR_M = 0.05
FAR_M = 5.0


@dataclass(frozen=True)
class Capture:
    """One camera's picture: RGB (height x width x 3, uint8) and depth along the optical
    axis (height x width, float32, m)."""

    camera: Camera
    rgb: np.ndarray
    depth_m: np.ndarray


def capture(client: int, camera: Camera) -> Capture:
    """Render ``camera`` in the PyBullet client ``client``."""
    rotation = camera.rotation.as_matrix()
    eye = np.asarray(camera.pose.position_m)
    forward, down = rotation[:, 2], rotation[:, 1]
    view = p.computeViewMatrix(
        cameraEyePosition=eye.tolist(),
        cameraTargetPosition=(eye + forward).tolist(),
        cameraUpVector=(-down).tolist(),
        physicsClientId=client,
    )
    projection = _projection(camera)
    _, _, rgba, depth_buffer, _ = p.getCameraImage(
        camera.width,
        camera.height,
        view,
        projection,
        renderer=p.ER_TINY_RENDERER,
        physicsClientId=client,
    )
    shape = (camera.height, camera.width)
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(*shape, 4)[:, :, :3]
    buffer = np.asarray(depth_buffer, dtype=np.float64).reshape(shape)
    depth = FAR_M * NEAR_M / (FAR_M - (FAR_M - NEAR_M) * buffer)
    return Capture(camera=camera, rgb=rgb, depth_m=depth.astype(np.float32))


def shown_pictures(client: int) -> tuple[Picture, ...]:
    """The image tier's pictures of the scene in ``client`` now (``world/pictures.py``:
    SHOWN, in its order), PNG-encoded as an agent call carries them."""
    pictures = []
    for camera, kinds in SHOWN:
        seen = capture(client, camera)
        for kind in kinds:
            png = colour_png(seen.rgb) if kind is PictureKind.COLOUR else depth_png(seen.depth_m)
            pictures.append(Picture(camera.name, kind, png))
    return tuple(pictures)


def _projection(camera: Camera) -> list[float]:
    """The projection matrix (column-major) of the camera's intrinsics, for TinyRenderer,
    which samples column i at x = 2 i / width - 1 of the normalised device range and row j
    (from the top) at y = 1 - 2 (j + 1) / height: so pixel (u, v) shows what the camera
    model puts at (u, v). (With OpenGL's pixel centres, i + 0.5, every brick was seen half a
    pixel off, 1.1 mm from above.)"""
    w, h, n, f = camera.width, camera.height, NEAR_M, FAR_M
    matrix = np.array(
        [
            [2 * camera.fx / w, 0.0, 1 - 2 * camera.cx / w, 0.0],
            [0.0, 2 * camera.fy / h, 2 * (camera.cy + 1) / h - 1, 0.0],
            [0.0, 0.0, -(f + n) / (f - n), -2 * f * n / (f - n)],
            [0.0, 0.0, -1.0, 0.0],
        ]
    )
    return matrix.T.flatten().tolist()
