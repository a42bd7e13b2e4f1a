"""Clearance of the arm, the gripper and a held brick from bricks and the ground.

Runs on the kinematic copy of the arm (its own PyBullet client, never stepped), so
collision queries cannot change the simulation. Distances come from PyBullet's closest
points: negative means penetration.
"""

from __future__ import annotations

from collections.abc import Sequence

import pybullet as p

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.world.boxes import Box
from actionreasoning.world.clearance import SEARCH_DISTANCE_M, Clearance
from actionreasoning.world.geometry import Joints, Vec3

#: Arm links that can come near the ground (the elbow and everything after it).
FIRST_GROUND_LINK = 3
PARKED = (0.0, 0.0, -100.0)


class CollisionChecker:
    """Distance queries against obstacles placed in the kinematic copy's client."""

    def __init__(self, arm: KinematicArm) -> None:
        self.arm = arm
        cid = arm.client
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        self._ground = p.createMultiBody(0.0, plane, physicsClientId=cid)
        self._pool: list[tuple[Vec3, int]] = []
        self._link_names = {
            j: p.getJointInfo(arm.robot, j, physicsClientId=cid)[12].decode()
            for j in range(p.getNumJoints(arm.robot, physicsClientId=cid))
        }

    def clearance(
        self,
        joints_rad: Joints,
        finger_half_width_m: float,
        obstacles: Sequence[Box],
        held: Box | None = None,
    ) -> Clearance:
        """Smallest distance of the arm (and ``held``) to ``obstacles`` and the ground; each
        box is named after its brick id."""
        self.arm.set_configuration(joints_rad, finger_half_width_m)
        bodies = self._place([*obstacles, *([held] if held else [])])
        named = {body: _name(box) for body, box in zip(bodies, obstacles, strict=False)}
        best = Clearance(SEARCH_DISTANCE_M, "nothing within reach of the query")
        cid, robot = self.arm.client, self.arm.robot
        for link, link_name in self._link_names.items():
            targets = list(named.items())
            if link >= FIRST_GROUND_LINK:
                targets.append((self._ground, "ground"))
            for body, name in targets:
                best = _closer(best, robot, body, link, f"{link_name} vs {name}", cid)
        if held is not None:
            held_body = bodies[-1]
            for body, name in [*named.items(), (self._ground, "ground")]:
                best = _closer(best, held_body, body, -1, f"held {_name(held)} vs {name}", cid)
        return best

    def _place(self, boxes: Sequence[Box]) -> list[int]:
        """Move pool bodies onto ``boxes`` (creating what is missing), park the rest."""
        cid = self.arm.client
        free = list(self._pool)
        used: list[int] = []
        for box in boxes:
            match = next((slot for slot in free if slot[0] == box.size_m), None)
            if match is None:
                shape = p.createCollisionShape(
                    p.GEOM_BOX, halfExtents=[s / 2.0 for s in box.size_m], physicsClientId=cid
                )
                match = (box.size_m, p.createMultiBody(0.0, shape, physicsClientId=cid))
                self._pool.append(match)
            else:
                free.remove(match)
            p.resetBasePositionAndOrientation(
                match[1], box.position_m, box.quat_xyzw, physicsClientId=cid
            )
            used.append(match[1])
        for _, body in free:
            p.resetBasePositionAndOrientation(body, PARKED, (0, 0, 0, 1), physicsClientId=cid)
        return used


def _name(box: Box) -> str:
    return f"brick {box.id}"


def _closer(
    best: Clearance, body_a: int, body_b: int, link_a: int, between: str, cid: int
) -> Clearance:
    points = p.getClosestPoints(
        body_a, body_b, SEARCH_DISTANCE_M, linkIndexA=link_a, physicsClientId=cid
    )
    if not points:
        return best
    distance = min(point[8] for point in points)
    return Clearance(distance, between) if distance < best.distance_m else best
