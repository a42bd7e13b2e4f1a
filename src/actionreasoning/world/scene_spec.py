"""Scene specification: brick properties, the pick and build areas, and the arm's reach.

The numbers are measured, not guessed: ``bench/reach_band.py`` sweeps top-down grasps
over radius and height and prints the band in which the arm's IK converges with margin.
"""

from __future__ import annotations

import math
from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, PositiveFloat

from actionreasoning.world.geometry import MAX_COORDINATE_M, Vec3

#: The gripper (sim/assets/gripper.urdf.xml; sim/robot_model.py takes these from here): the
#: gap between its pads closed and fully open (the finger joints' limits, doubled), and how
#: far its fingertips reach beyond the tool centre point and its palm sits behind it.
GRIPPER_GAP_M = (0.06, 0.16)
FINGERTIPS_BEYOND_TCP_M = 0.02
PALM_BEHIND_TCP_M = 0.05
#: How long each finger pad is along the brick (the URDF's finger box, along the tool's x).
PAD_LENGTH_M = 0.04
#: How far the tool rises straight up after letting go of a brick, before it moves on.
RETREAT_M = 0.08

#: An azimuth about the base (deg), as atan2 gives it.
Azimuth = Annotated[float, Field(ge=-180.0, le=180.0)]
#: A coordinate of the workspace box (m): no farther from the base than a tool is asked about.
Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_M, le=MAX_COORDINATE_M)]
#: A distance from the base (m) within the same bound, so that a target the reach band
#: admits has coordinates within it.
Reach = Annotated[float, Field(ge=0.0, le=MAX_COORDINATE_M)]


class ReachBand(BaseModel):
    """Where a top-down tool centre point can go: an annulus around the base, up to a height."""

    model_config = ConfigDict(frozen=True)

    min_radius_m: Reach = 0.42
    max_radius_m: Reach = 0.76
    max_height_m: Reach = 0.45
    #: The base joint's limit (the iiwa's A1, +-170 deg): a top-down tool farther round is
    #: reached, if at all, only with the arm folded back over its base.
    max_azimuth_deg: Annotated[float, Field(ge=0.0, le=180.0)] = 170.0

    def contains(self, x: float, y: float, z: float) -> bool:
        """Whether a top-down grasp centre at (x, y, z) lies inside the band."""
        radius = math.hypot(x, y)
        return self.min_radius_m <= radius <= self.max_radius_m and 0.0 <= z <= self.max_height_m


class WorkspaceBox(BaseModel):
    """The box (world frame, metres) every commanded tool position must lie in."""

    model_config = ConfigDict(frozen=True)

    low_m: tuple[Coordinate, Coordinate, Coordinate] = (-0.9, -0.9, 0.0)
    high_m: tuple[Coordinate, Coordinate, Coordinate] = (0.9, 0.9, 0.8)

    def contains(self, position: Vec3) -> bool:
        """Whether ``position`` lies inside the box."""
        return all(
            lo <= v <= hi for lo, v, hi in zip(self.low_m, position, self.high_m, strict=True)
        )


#: The workspace box: a scene's (``SceneSpec.workspace``), which every planned tool path must
#: stay in (``control/safety.py``), and the one the agents' answers are checked against
#: (``agents/validation.py``).
WORKSPACE = WorkspaceBox()


class BrickBody(BaseModel):
    """The physical properties of one spawned brick."""

    model_config = ConfigDict(frozen=True)

    size_m: Vec3
    mass_kg: float
    lateral_friction: float


#: The catalogue's bricks by name (m): a pattern's brick may name one instead of its edges.
BRICK_CATALOGUE: dict[str, Vec3] = {"full": (0.20, 0.095, 0.06), "half": (0.095, 0.095, 0.06)}


class SceneSpec(BaseModel):
    """Everything that defines a scene apart from the goal pattern and the seed."""

    model_config = ConfigDict(frozen=True)

    brick_size_m: tuple[PositiveFloat, PositiveFloat, PositiveFloat] = Field(
        BRICK_CATALOGUE["full"],
        description="The catalogue's full brick; a pattern may use another size.",
    )
    brick_mass_kg: PositiveFloat = Field(1.5, description="The catalogue brick's mass.")
    build_radius_m: Reach = 0.58
    build_azimuth_deg: Azimuth = 40.0
    pick_radius_m: tuple[Reach, Reach] = (0.44, 0.72)
    pick_azimuth_deg: tuple[Azimuth, Azimuth] = (-150.0, -15.0)
    pick_min_spacing_m: PositiveFloat = Field(
        0.24, description="Minimum centre distance of spawned catalogue bricks."
    )
    reach: ReachBand = ReachBand()
    workspace: WorkspaceBox = WORKSPACE

    def brick_body(self, lateral_friction: float, size_m: Vec3 | None = None) -> BrickBody:
        """A catalogue brick of ``size_m`` (default: this spec's size) with the given
        friction; its mass is this spec's brick mass scaled by volume (the same density)."""
        size = self.brick_size_m if size_m is None else size_m
        mass = self.brick_mass_kg * (math.prod(size) / math.prod(self.brick_size_m))
        return BrickBody(size_m=size, mass_kg=mass, lateral_friction=lateral_friction)

    def pick_spacing_m(self, size_m: Vec3) -> float:
        """Least centre distance of spawned bricks of ``size_m``: the minimum spacing, widened
        in proportion to a footprint whose diagonal is longer than this spec's brick's."""
        widen = math.hypot(*size_m[:2]) / math.hypot(*self.brick_size_m[:2])
        return self.pick_min_spacing_m * max(1.0, widen)

    @property
    def build_center_m(self) -> Vec3:
        """Centre of the build area on the ground."""
        azimuth = math.radians(self.build_azimuth_deg)
        return (
            self.build_radius_m * math.cos(azimuth),
            self.build_radius_m * math.sin(azimuth),
            0.0,
        )

    @property
    def build_yaw_rad(self) -> float:
        """Yaw of a build-area row: rows run tangentially, the bricks' short side faces the base."""
        return math.radians(self.build_azimuth_deg) + math.pi / 2.0
