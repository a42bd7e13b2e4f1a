"""The plain data of a clearance query: named boxes to keep clear of, and the answer.

The tools build the boxes and read the answer; ``sim/collision.py`` computes it.
"""

from __future__ import annotations

from dataclasses import dataclass

from actionreasoning.world.geometry import QuatXYZW, Vec3


@dataclass(frozen=True)
class Box:
    """A named box in the world frame."""

    name: str
    position_m: Vec3
    quat_xyzw: QuatXYZW
    size_m: Vec3


@dataclass(frozen=True)
class Clearance:
    """The smallest distance found and between what."""

    distance_m: float
    between: str
