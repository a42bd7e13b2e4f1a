"""Walls (world/walls.py): the built-in ``wall`` brick by brick, the bonds, the lengths, and
each refusal in one line."""

from __future__ import annotations

import itertools

import pytest

from actionreasoning.errors import PatternError
from actionreasoning.world.models import Supply
from actionreasoning.world.pattern_file import PatternFile, brick_sizes
from actionreasoning.world.patterns import builtin_pattern, load_pattern
from actionreasoning.world.scenarios import PATTERNS
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, SceneSpec
from actionreasoning.world.walls import (
    JOINT_M,
    Bond,
    full_bricks_per_course,
    wall_length_m,
    wall_pattern,
)

SPEC = SceneSpec()
FULL, HALF = BRICK_CATALOGUE["full"], BRICK_CATALOGUE["half"]

#: The built-in wall, by hand: 4 full bricks 0.20 m long, 10 mm apart, centred on x = 0
#: (0.83 m from end to end); the middle course a half brick (0.095 m), 3 full ones and a
#: half brick, flush with the courses below and above; each course 0.06 m high.
WALL = [
    *((x, 0.03, None) for x in (-0.315, -0.105, 0.105, 0.315)),
    (-0.3675, 0.09, "half"),
    *((x, 0.09, None) for x in (-0.21, 0.0, 0.21)),
    (0.3675, 0.09, "half"),
    *((x, 0.15, None) for x in (-0.315, -0.105, 0.105, 0.315)),
]


def courses(pattern: PatternFile) -> list[list[tuple[float, float]]]:
    """Each course's bricks, bottom first, as (x of the -x end, x of the +x end)."""
    by_z: dict[float, list[tuple[float, float]]] = {}
    for brick, size in zip(pattern.bricks, brick_sizes(pattern), strict=True):
        x, _, z = brick.position
        by_z.setdefault(z, []).append((x - size[0] / 2.0, x + size[0] / 2.0))
    return [by_z[z] for z in sorted(by_z)]


def joints(course: list[tuple[float, float]]) -> list[float]:
    """The middle of each joint of a course (m along x)."""
    return [(end + start) / 2.0 for (_, end), (start, _) in itertools.pairwise(course)]


def test_the_builtin_wall_brick_by_brick() -> None:
    wall = builtin_pattern("wall", SPEC)
    assert (wall.name, wall.brick_size, wall.supply, wall.origin) == (
        "wall",
        FULL,
        Supply.PALLET,
        None,
    )
    assert len(wall.bricks) == 13
    for brick, (x, z, size) in zip(wall.bricks, WALL, strict=True):
        assert brick.position == pytest.approx((x, 0.0, z), abs=1e-9)
        assert brick.yaw_deg == 0.0
        assert brick.size == (None if size is None else HALF)
    assert wall_length_m(4) == pytest.approx(0.83)
    for course in courses(wall):
        assert course[0][0] == pytest.approx(-0.415) and course[-1][1] == pytest.approx(0.415)


def test_the_builtin_wall_is_a_pattern_of_the_registry() -> None:
    """Loaded and validated as ``--pattern wall`` loads it: its supply, its joint as the
    gap, a half brick at each end of the middle course.

    Fails while the pick area's capacity (12 bricks) is checked for every supply: the
    per-supply capacity lets the pallet hold the wall's 13."""
    goal = load_pattern("wall", SPEC)
    assert (goal.name, goal.supply, goal.gap_m, len(goal.targets)) == (
        "wall",
        Supply.PALLET,
        JOINT_M,
        13,
    )
    assert [i for i, t in enumerate(goal.targets) if t.size_m == HALF] == [4, 8]
    assert "wall" in PATTERNS


def test_stack_bond_lays_every_course_alike() -> None:
    wall = wall_pattern(0.83, 3, Bond.STACK)
    assert len(wall.bricks) == 12 and all(b.size is None for b in wall.bricks)
    first, *others = courses(wall)
    assert all(course == first for course in others)


@pytest.mark.parametrize(
    ("length_m", "full"), [(0.83, 4), (0.80, 4), (0.9, 4), (0.72, 3), (0.41, 2), (1.04, 5)]
)
def test_a_course_takes_the_full_bricks_nearest_the_length(length_m: float, full: int) -> None:
    assert full_bricks_per_course(length_m) == full
    wall = wall_pattern(length_m, 2, Bond.RUNNING)
    bottom, top = courses(wall)
    assert len(bottom) == full and len(top) == full + 1
    assert bottom[-1][1] - bottom[0][0] == pytest.approx(wall_length_m(full))


@pytest.mark.parametrize("bond", list(Bond))
def test_every_course_is_centred_with_joints_and_built_from_one_end(bond: Bond) -> None:
    wall = wall_pattern(0.83, 4, bond)
    for course in courses(wall):
        assert course[0][0] == pytest.approx(-course[-1][1])
        for (_, end), (start, _) in itertools.pairwise(course):
            assert start - end == pytest.approx(JOINT_M)
    order = [(b.position[2], b.position[0]) for b in wall.bricks]
    assert order == sorted(order)


def test_a_running_bond_staggers_the_joints_by_half_a_brick() -> None:
    bottom, middle, top = courses(wall_pattern(0.83, 3, Bond.RUNNING))
    shift = (FULL[0] + JOINT_M) / 2.0
    below = joints(bottom)
    assert joints(middle) == pytest.approx([x - shift for x in below] + [below[-1] + shift])
    assert top == bottom


@pytest.mark.parametrize(
    ("length_m", "count", "bond", "needle"),
    [
        (0.83, 0, Bond.RUNNING, "courses: 0; a wall has at least 1 course"),
        (-1.0, 3, Bond.RUNNING, "length: -1 m is not a positive length"),
        (float("inf"), 3, Bond.RUNNING, "length: inf m is not a positive length"),
        (0.25, 3, Bond.RUNNING, "fits 1 full brick a course; a running bond needs 2"),
        (0.05, 3, Bond.STACK, "fits 0 full bricks a course; a stack bond needs 1"),
        (1e6, 3, Bond.RUNNING, "at most 10000 are generated"),
    ],
)
def test_a_wall_that_cannot_be_laid_is_refused(
    length_m: float, count: int, bond: Bond, needle: str
) -> None:
    with pytest.raises(PatternError, match=r"^wall 'wall': ") as refused:
        wall_pattern(length_m, count, bond)
    assert needle in str(refused.value) and "\n" not in str(refused.value)
