"""A look-alike of a scene in a simulator client of its own, for rendering elsewhere.

A :class:`SceneLooks` (the bricks' sizes and colours) rebuilds the arm and the bricks, with
no ground and no physics, in another client, in this process or another; a
:class:`ScenePose` (every joint's angle, every brick's pose) read from the scene at one
moment poses it. Rendering the replica then shows what rendering the scene would, while the
scene's own client is only read, never touched (tests check both).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from actionreasoning.sim.robot_model import load_robot
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import Vec3

RGBA = tuple[float, float, float, float]


@dataclass(frozen=True)
class SceneLooks:
    """What a scene's bricks look like: each one's size (m) and colour."""

    brick_sizes_m: tuple[Vec3, ...]
    brick_colors: tuple[RGBA, ...]

    @classmethod
    def of(cls, scene: Scene) -> SceneLooks:
        """The looks of ``scene``'s bricks, read from their visual shapes."""
        shapes = [p.getVisualShapeData(b, physicsClientId=scene.client)[0] for b in scene.bricks]
        return cls(
            brick_sizes_m=tuple(tuple(shape[3]) for shape in shapes),
            brick_colors=tuple(tuple(shape[7]) for shape in shapes),
        )


@dataclass(frozen=True)
class ScenePose:
    """Where everything visible is: the robot's joint angles (rad, every joint) and each
    brick's position and orientation (x, y, z, qx, qy, qz, qw)."""

    joints_rad: np.ndarray
    bricks: np.ndarray

    @classmethod
    def of(cls, scene: Scene) -> ScenePose:
        """``scene``'s pose now."""
        cid, robot = scene.client, scene.robot
        joints = p.getJointStates(
            robot, range(p.getNumJoints(robot, physicsClientId=cid)), physicsClientId=cid
        )
        bricks = [p.getBasePositionAndOrientation(b, physicsClientId=cid) for b in scene.bricks]
        return cls(
            joints_rad=np.array([state[0] for state in joints]),
            bricks=np.array([[*position, *quat] for position, quat in bricks]).reshape(-1, 7),
        )


class Replica:
    """The arm and the bricks of ``looks`` in a client of their own (``client``), posed by
    ``show``; no ground, no physics. ``close()`` ends the client."""

    def __init__(self, looks: SceneLooks) -> None:
        self.client = p.connect(p.DIRECT)
        try:
            self.robot = load_robot(self.client)
            self.bricks = [
                self._brick(size, color)
                for size, color in zip(looks.brick_sizes_m, looks.brick_colors, strict=True)
            ]
        except Exception:
            p.disconnect(self.client)
            raise

    def _brick(self, size_m: Vec3, color: RGBA) -> int:
        visual = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=[s / 2.0 for s in size_m],
            rgbaColor=color,
            physicsClientId=self.client,
        )
        return p.createMultiBody(baseVisualShapeIndex=visual, physicsClientId=self.client)

    def show(self, pose: ScenePose) -> None:
        """Put every joint and brick where ``pose`` has them."""
        cid = self.client
        for joint, angle in enumerate(pose.joints_rad):
            p.resetJointState(self.robot, joint, float(angle), physicsClientId=cid)
        for body, row in zip(self.bricks, pose.bricks, strict=True):
            p.resetBasePositionAndOrientation(body, row[:3], row[3:], physicsClientId=cid)

    def close(self) -> None:
        p.disconnect(self.client)
