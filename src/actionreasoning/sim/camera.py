"""Headless pictures of the scene with PyBullet's TinyRenderer (no display needed).

Rendering reads the scene but never steps or changes it, so taking snapshots does not
alter a trial's outcome (tests check this).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pybullet as p
import pybullet_data

from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import Vec3


@dataclass(frozen=True)
class CameraView:
    """A look-at camera: target point, distance (m), yaw and pitch (deg)."""

    target_m: Vec3
    distance_m: float
    yaw_deg: float
    pitch_deg: float
    fov_deg: float = 50.0


def overview(scene: Scene) -> CameraView:
    """The whole workspace from above the arm's back: pick area, arm and build area."""
    return CameraView(target_m=(0.2, 0.0, 0.1), distance_m=2.0, yaw_deg=0.0, pitch_deg=-70.0)


def closeup(target_m: Vec3) -> CameraView:
    """A close look at a point on the ground, from outside the arm's reach, facing the arm."""
    azimuth = math.degrees(math.atan2(target_m[1], target_m[0]))
    return CameraView(
        target_m=(target_m[0], target_m[1], 0.08),
        distance_m=0.9,
        yaw_deg=azimuth + 90.0,
        pitch_deg=-30.0,
    )


def build_closeup(scene: Scene) -> CameraView:
    """The build area seen from outside, facing the arm."""
    return closeup(scene.spec.build_center_m)


def render(scene: Scene, view: CameraView, width: int = 480, height: int = 360) -> np.ndarray:
    """An RGB image (height x width x 3, uint8) of the scene from ``view``."""
    return _camera_image(scene.client, view, width, height)[0]


class FixedCamera:
    """One view filmed frame after frame, fast: TinyRenderer spends most of a frame on the
    ground (a 100 m textured plane), so the ground is rendered once, in a client of its own,
    and each frame renders a client without ground (a :class:`~.replica.Replica`) and lays
    it over that picture."""

    def __init__(self, view: CameraView, width: int, height: int) -> None:
        self.view, self.width, self.height = view, width, height
        client = p.connect(p.DIRECT)
        try:
            p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=client)
            p.loadURDF("plane.urdf", physicsClientId=client)
            self._ground = _camera_image(client, view, width, height)[0]
        finally:
            p.disconnect(client)

    def render(self, client: int) -> np.ndarray:
        """An RGB image (height x width x 3, uint8) of what ``client`` holds, on the ground."""
        rgb, segments = _camera_image(client, self.view, self.width, self.height)
        return np.where((segments < 0)[:, :, None], self._ground, rgb)


def _camera_image(
    client: int, view: CameraView, width: int, height: int
) -> tuple[np.ndarray, np.ndarray]:
    """The RGB image and the segmentation mask (body id per pixel, -1: nothing) of ``view``."""
    view_matrix = p.computeViewMatrixFromYawPitchRoll(
        cameraTargetPosition=view.target_m,
        distance=view.distance_m,
        yaw=view.yaw_deg,
        pitch=view.pitch_deg,
        roll=0.0,
        upAxisIndex=2,
        physicsClientId=client,
    )
    projection = p.computeProjectionMatrixFOV(
        fov=view.fov_deg, aspect=width / height, nearVal=0.05, farVal=5.0, physicsClientId=client
    )
    _, _, rgba, _, segments = p.getCameraImage(
        width, height, view_matrix, projection, renderer=p.ER_TINY_RENDERER, physicsClientId=client
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3]
    return rgb, np.asarray(segments, dtype=np.int64).reshape(height, width)
