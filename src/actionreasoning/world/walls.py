"""Straight walls of catalogue bricks, generated as pattern files in the build-area frame.

A wall is ``courses`` courses of bricks laid lengthwise along x (the build row), centred on
x = 0, each course directly on the one below (no bed joint). In ``running`` bond the odd
courses (1, 3, ...) are full bricks and the even ones are shifted by half a brick, with a
half brick at each end; in ``stack`` bond every course is the odd one. The wall is built
course by course, each from its -x end to its +x end, so a brick rests on earlier ones.
"""

from __future__ import annotations

import math
from enum import StrEnum

from actionreasoning.errors import PatternError
from actionreasoning.world.models import Supply
from actionreasoning.world.pattern_file import PatternFile
from actionreasoning.world.scene_spec import BRICK_CATALOGUE

#: The head joint between neighbouring bricks of a course: a mason's standard 10 mm. With
#: it, a catalogue half brick is half a full brick less half a joint, so the ends of a
#: running-bond wall are flush.
JOINT_M = 0.010
#: The most bricks a wall is generated with: far more than any supply or the arm's reach
#: takes, so a mistyped length is refused before it fills the memory.
MAX_BRICKS = 10_000


class Bond(StrEnum):
    """How a wall's courses are laid over each other."""

    RUNNING = "running"  # every second course shifted by half a brick: joints staggered
    STACK = "stack"  # every course alike: joints over joints


def full_bricks_per_course(length_m: float, joint_m: float = JOINT_M) -> int:
    """The full bricks a course of about ``length_m`` takes: the nearest whole n to
    n * L + (n - 1) * joint = length_m (halves rounded up; the quotient is taken to a
    billionth, so that a length meant as a half, 0.305 m, is not read as just under one)."""
    length = BRICK_CATALOGUE["full"][0]
    return math.floor(round((length_m + joint_m) / (length + joint_m), 9) + 0.5)


def wall_length_m(full_bricks: int, joint_m: float = JOINT_M) -> float:
    """The length (m) of a course of ``full_bricks`` full bricks with joints between."""
    return full_bricks * BRICK_CATALOGUE["full"][0] + (full_bricks - 1) * joint_m


def wall_pattern(
    length_m: float,
    courses: int,
    bond: Bond,
    joint_m: float = JOINT_M,
    supply: Supply = Supply.PALLET,
    name: str = "wall",
) -> PatternFile:
    """A straight wall about ``length_m`` long (the full bricks that fit, see
    :func:`full_bricks_per_course`) of ``courses`` courses in ``bond``, built from ``supply``.

    Full bricks have the pattern's ``brick_size`` (``full``), half bricks ``size: half``;
    positions are rounded to the micrometre. A wall that cannot be laid is refused in one
    line naming it and the field; reach, supply and support are checked when the pattern is
    loaded (:func:`~actionreasoning.world.patterns.load_pattern`).
    """
    source = f"wall '{name}'"
    if courses < 1:
        raise PatternError(f"{source}: courses: {courses}; a wall has at least 1 course")
    if not math.isfinite(length_m) or length_m <= 0.0:
        raise PatternError(f"{source}: length: {length_m:g} m is not a positive length")
    longest = wall_length_m(MAX_BRICKS, joint_m)
    if length_m > longest:
        raise PatternError(
            f"{source}: length: {length_m:g} m is longer than the longest wall generated "
            f"({longest:g} m, {MAX_BRICKS} full bricks a course)"
        )
    full = full_bricks_per_course(length_m, joint_m)
    least = 2 if bond is Bond.RUNNING else 1
    if full < least:
        shortest = (least - 0.5) * (BRICK_CATALOGUE["full"][0] + joint_m) - joint_m
        raise PatternError(
            f"{source}: length: {length_m:g} m fits {full} full brick{'s' * (full != 1)} a "
            f"course; a {bond} bond needs {least} (a length of at least {shortest:.3f} m)"
        )
    count = full * courses + (courses // 2 if bond is Bond.RUNNING else 0)
    if count > MAX_BRICKS:
        raise PatternError(
            f"{source}: {count} bricks ({full} full a course, {courses} courses); "
            f"at most {MAX_BRICKS} are generated"
        )
    height = BRICK_CATALOGUE["full"][2]
    bricks = [
        {"position": [_um(x), 0.0, _um((k + 0.5) * height)], "yaw_deg": 0.0}
        | ({} if piece == "full" else {"size": piece})
        for k in range(courses)
        for x, piece in _laid(_course(full, bond is Bond.RUNNING and k % 2 == 1), joint_m)
    ]
    data = {"name": name, "brick_size": "full", "supply": supply, "bricks": bricks}
    return PatternFile.model_validate(data)


def _um(value_m: float) -> float:
    """``value_m`` rounded to the micrometre (never -0.0)."""
    return round(value_m, 6) + 0.0


def _course(full: int, shifted: bool) -> list[str]:
    """The bricks of a course by catalogue name, from its -x end: ``full`` full bricks, or,
    shifted by half a brick, a half brick at each end and ``full - 1`` full ones between."""
    return ["half", *["full"] * (full - 1), "half"] if shifted else ["full"] * full


def _laid(course: list[str], joint_m: float) -> list[tuple[float, str]]:
    """Each brick's centre x (m) and name, the course centred on x = 0, ``joint_m`` apart."""
    lengths = [BRICK_CATALOGUE[piece][0] for piece in course]
    left = -(sum(lengths) + joint_m * (len(course) - 1)) / 2.0  # the course's -x end
    laid = []
    for length, piece in zip(lengths, course, strict=True):
        laid.append((left + length / 2.0, piece))
        left += length + joint_m
    return laid
