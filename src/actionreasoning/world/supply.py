"""Where the bricks wait at the start of a trial, by the pattern's :class:`Supply`.

- ``scattered``: on the ground at random poses in the pick area (:mod:`.layout`).
- ``pallet``: in layers on a pallet, a straight row of PALLET_STACKS stacks in the pick area,
  each brick's length pointing at the arm's base. A cell of a layer holds a full brick or two
  half bricks end to end (a half brick and a joint are a full brick's length, as on a
  mason's pallet). It is loaded layer by layer in the build's reverse order, so the bricks
  the build takes first lie on top. The pallet's place along the pick area, which stack each
  cell of a layer goes to, and a small misalignment of each brick (PALLET_JITTER_M,
  PALLET_JITTER_DEG) are drawn from the trial's seed. Only a stack's top brick is free.
- ``feeder``: one brick at :func:`feeder_pose`, the rest queued in the pattern's order behind
  the arm (``sim/scene.py`` feeds the next when the last has been carried away).

Pallet sizes are derived from what must pass between and over the stacks: stacks are
PALLET_PITCH_M apart across the bricks' width, which leaves each open pad (the gripper opens
to GRIPPER_GAP_M[1]) more than the least clearance c_min (22 mm) from the next stack; and
PALLET_LAYERS layers (0.18 m) stay below what the classical script's fixed transfer height
(0.30 m) carries a brick over, with a brick's height to spare.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.world.geometry import Vec3, yaw_quat
from actionreasoning.world.layout import pick_capacity, sample_pick_poses, spawn_size
from actionreasoning.world.models import Pose, Supply
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, SceneSpec

PALLET_STACKS = 6
PALLET_LAYERS = 3
PALLET_PITCH_M = 0.18
#: The gap between two half bricks sharing a cell (m): their pair is a full brick long.
HALF_PAIR_GAP_M = BRICK_CATALOGUE["full"][0] - 2 * BRICK_CATALOGUE["half"][0]
#: How far each half brick of a pair lies from its cell's centre, along the bricks' length.
PAIR_SHIFT_M = (HALF_PAIR_GAP_M + BRICK_CATALOGUE["half"][0]) / 2.0
PALLET_JITTER_M = 0.002
PALLET_JITTER_DEG = 2.0
#: The feeder's pose: mid-radius of the pick area, in the middle of its azimuths, the brick's
#: length pointing at the arm's base.
FEEDER_RADIUS_M = 0.58
FEEDER_AZIMUTH_DEG = -82.5
#: The feeder's queue waits on the ground behind the arm, beyond its reach, in rows of
#: QUEUE_ROW bricks QUEUE_SPACING_M apart; it holds FEEDER_CAPACITY bricks (the last row
#: within the simulated world's bounds).
QUEUE_X_M = -1.2
QUEUE_SPACING_M = 0.3
QUEUE_ROW = 6
FEEDER_CAPACITY = 36


@dataclass(frozen=True)
class SupplyLayout:
    """The bricks' poses at the start, and the feeder's queue (brick ids, next first)."""

    poses: tuple[Pose, ...]
    queue: tuple[int, ...] = ()


def capacity_error(supply: Supply, sizes: Sequence[Vec3], spec: SceneSpec) -> str | None:
    """Why ``supply`` cannot hold bricks of ``sizes`` (None: it can)."""
    if supply is Supply.SCATTERED:
        size = spawn_size(sizes, spec)
        capacity = pick_capacity(spec, size)
        if len(sizes) > capacity:
            return (
                f"{len(sizes)} bricks, but the pick area holds at most {capacity} bricks of "
                f"{_fmt(size)} m ({spec.pick_spacing_m(size):.3f} m apart)"
            )
        return None
    if supply is Supply.PALLET:
        foreign = [s for s in sizes if s not in BRICK_CATALOGUE.values()]
        if foreign:
            return f"a pallet holds catalogue bricks only (full, half), not {_fmt(foreign[0])} m"
        cells, most = len(_cells(sizes)), PALLET_STACKS * PALLET_LAYERS
        if cells > most:
            return (
                f"{len(sizes)} bricks take {cells} pallet cells (a full brick or two half "
                f"bricks each), but a pallet holds {most} ({PALLET_STACKS} stacks of "
                f"{PALLET_LAYERS} layers)"
            )
        return None
    if len(sizes) > FEEDER_CAPACITY:
        return f"{len(sizes)} bricks, but the feeder's queue holds {FEEDER_CAPACITY}"
    return None


def lay_out(
    supply: Supply,
    sizes: Sequence[Vec3],
    heights: Sequence[float],
    spec: SceneSpec,
    rng: np.random.Generator,
) -> SupplyLayout:
    """The bricks of nominal ``sizes`` (in the pattern's order) in the supply, each lying on
    what is under it by its spawned height (``heights``)."""
    if supply is Supply.SCATTERED:
        poses = sample_pick_poses(rng, len(sizes), spec, spawn_size(sizes, spec))
        return SupplyLayout(
            tuple(
                _at_height(pose, height / 2.0) for pose, height in zip(poses, heights, strict=True)
            )
        )
    if supply is Supply.PALLET:
        return SupplyLayout(_pallet(sizes, heights, spec, rng))
    queued = [
        Pose(
            position_m=(
                QUEUE_X_M - QUEUE_SPACING_M * (k // QUEUE_ROW),
                QUEUE_SPACING_M * (k % QUEUE_ROW - (QUEUE_ROW - 1) / 2.0),
                height / 2.0,
            )
        )
        for k, height in enumerate(heights[1:])
    ]
    return SupplyLayout(
        (_at_height(feeder_pose(), heights[0] / 2.0), *queued), queue=tuple(range(1, len(sizes)))
    )


def feeder_pose() -> Pose:
    """Where the feeder puts each brick (its z: a catalogue brick's half height)."""
    azimuth = math.radians(FEEDER_AZIMUTH_DEG)
    return Pose(
        position_m=(
            FEEDER_RADIUS_M * math.cos(azimuth),
            FEEDER_RADIUS_M * math.sin(azimuth),
            BRICK_CATALOGUE["full"][2] / 2.0,
        ),
        quat_xyzw=yaw_quat(azimuth),
    )


def _at_height(pose: Pose, z: float) -> Pose:
    return pose.model_copy(update={"position_m": (*pose.position_m[:2], z)})


def _cells(sizes: Sequence[Vec3]) -> list[list[int]]:
    """The pallet's cells in the order the build takes them, each the bricks it holds: a full
    brick, or two half bricks (the first two halves, the next two, ...)."""
    half = BRICK_CATALOGUE["half"]
    halves = [i for i, s in enumerate(sizes) if s == half]
    pairs = [halves[k : k + 2] for k in range(0, len(halves), 2)]
    cells = [[i] for i, s in enumerate(sizes) if s != half] + pairs
    return sorted(cells, key=min)


def _pallet(
    sizes: Sequence[Vec3], heights: Sequence[float], spec: SceneSpec, rng: np.random.Generator
) -> tuple[Pose, ...]:
    """The pallet loaded layer by layer in the build's reverse order, so the bricks the build
    takes first lie on top; which stack each cell of a layer goes to is drawn."""
    if (error := capacity_error(Supply.PALLET, sizes, spec)) is not None:
        raise ConfigError(error)
    cells = _cells(sizes)[::-1]
    # The row as far out as keeps every brick's centre (a half brick of a pair lies
    # PAIR_SHIFT_M off its stack's centre) inside the pick area's radii; the row's centre is
    # drawn where its ends stay inside the pick area's azimuths.
    half_row = PALLET_PITCH_M * (PALLET_STACKS - 1) / 2.0
    radius = math.sqrt(spec.pick_radius_m[1] ** 2 - half_row**2) - PAIR_SHIFT_M
    half_span = math.degrees(math.atan2(half_row, radius))
    low, high = spec.pick_azimuth_deg
    azimuth = math.radians(rng.uniform(low + half_span, high - half_span))
    radial = np.array([math.cos(azimuth), math.sin(azimuth)])  # the bricks' length axis
    tangent = np.array([-radial[1], radial[0]])
    tops = [0.0] * PALLET_STACKS
    poses: dict[int, Pose] = {}
    for first in range(0, len(cells), PALLET_STACKS):
        layer = cells[first : first + PALLET_STACKS]
        for cell, stack in zip(layer, rng.permutation(PALLET_STACKS), strict=False):
            offset = PALLET_PITCH_M * (stack - (PALLET_STACKS - 1) / 2.0)
            centre = radial * radius + tangent * offset
            sides = [0.0] if len(cell) == 1 else [-1.0, 1.0]
            for brick, side in zip(cell, sides, strict=True):
                shift = side * PAIR_SHIFT_M
                dx, dy = rng.uniform(-PALLET_JITTER_M, PALLET_JITTER_M, size=2)
                turn = math.radians(rng.uniform(-PALLET_JITTER_DEG, PALLET_JITTER_DEG))
                x, y = centre + radial * shift + (dx, dy)
                poses[brick] = Pose(
                    position_m=(float(x), float(y), tops[stack] + heights[brick] / 2.0),
                    quat_xyzw=yaw_quat(azimuth + turn),
                )
            tops[stack] += max(heights[brick] for brick in cell)
    return tuple(poses[i] for i in range(len(sizes)))


def _fmt(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"
