"""Walls (world/walls.py): the built-in ``wall`` brick by brick, the bonds, the lengths, and
``actionreasoning pattern --wall``: the file it writes loads, and each refusal is one line."""

from __future__ import annotations

import itertools
import resource
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from conftest import assert_clean_error, cli

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
    ("length_m", "full"),
    [(0.83, 4), (0.80, 4), (0.9, 4), (0.72, 3), (0.41, 2), (1.04, 5), (0.305, 2), (0.515, 3)],
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
        (1e3, 3, Bond.RUNNING, "at most 10000 are generated"),
        (1e300, 3, Bond.RUNNING, "length: 1e+300 m is longer than the longest wall generated"),
        (1.7e308, 3, Bond.RUNNING, "1.7e+308 m is longer than the longest wall generated"),
        (0.304, 3, Bond.RUNNING, "(a length of at least 0.305 m)"),
    ],
)
def test_a_wall_that_cannot_be_laid_is_refused(
    length_m: float, count: int, bond: Bond, needle: str
) -> None:
    with pytest.raises(PatternError, match=r"^wall 'wall': ") as refused:
        wall_pattern(length_m, count, bond)
    assert needle in str(refused.value) and "\n" not in str(refused.value)


def test_the_generator_writes_a_four_course_running_wall_that_loads(tmp_path: Path) -> None:
    """The acceptance's wall: 4 courses of 4 full bricks, 18 bricks with four halves.

    Fails while the pick area's capacity (12 bricks) is checked for every supply."""
    out = tmp_path / "wall4.yaml"
    written = cli(
        "pattern", "--wall", "0.83", "--courses", "4", "--bond", "running", "--out", f"{out}"
    )
    assert written.returncode == 0, written.stderr
    assert "pattern wall4: 18 bricks, valid" in written.stdout
    assert f"wrote {out}" in written.stdout
    goal = load_pattern(out, SPEC)
    assert (len(goal.targets), goal.supply) == (18, Supply.PALLET)
    assert [i for i, t in enumerate(goal.targets) if t.size_m == HALF] == [4, 8, 13, 17]
    assert [p.name for p in tmp_path.iterdir()] == ["wall4.yaml"]


@pytest.mark.parametrize("suffix", [".json", ".yml"])
def test_a_generated_wall_from_a_feeder_round_trips(tmp_path: Path, suffix: str) -> None:
    out = tmp_path / f"fed{suffix}"
    args = ("--wall", "0.62", "--courses", "2", "--supply", "feeder", "--out", str(out))
    written = cli("pattern", *args)
    assert written.returncode == 0, written.stderr
    data = yaml.safe_load(out.read_text())  # JSON is YAML
    assert (data["supply"], data["brick_size"]) == ("feeder", "full")
    assert [b.get("size") for b in data["bricks"]] == [None] * 3 + ["half", None, None, "half"]
    generated = wall_pattern(0.62, 2, Bond.RUNNING, supply=Supply.FEEDER, name="fed")
    assert PatternFile.model_validate(data) == generated
    goal = load_pattern(out, SPEC)
    assert (goal.name, goal.supply, len(goal.targets)) == ("fed", Supply.FEEDER, 7)


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--courses", "0"], ["wall 'w': courses: 0"]),
        (["--wall", "-1"], ["wall 'w': length: -1 m"]),
        (["--wall", "0.2"], ["fits 1 full brick a course", "at least 0.305 m"]),
        (["--wall", "1.5"], ["w.json: brick 0 at world", "out of the arm's reach"]),
        (["--wall", "0.41", "--courses", "9"], ["w.json: brick 20", "0.510)", "arm's reach"]),
        (["--out", "w.txt"], ["w.txt: unknown extension '.txt'"]),
        (["--wall", "1e308"], ["1e+308 m is longer than the longest wall generated"]),
        (["--out", ""], ["--out '' names no file: give the pattern file to write"]),
        (["--out", "."], ["--out '.' names no file"]),
    ],
)
def test_the_generator_refuses_in_one_line_and_writes_nothing(
    tmp_path: Path, args: list[str], needles: list[str]
) -> None:
    """A wall that cannot be laid, one out of reach (too long or too high; reach is checked
    before the supply's capacity), or an unknown file type."""
    options = dict(zip(["--wall", "--courses", "--out"], ["0.83", "3", "w.json"], strict=True))
    options.update(zip(args[::2], args[1::2], strict=True))
    refused = cli("pattern", *itertools.chain(*options.items()), cwd=tmp_path)
    assert_clean_error(refused, *needles)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        ([], "give a PATTERN (a built-in or a file) or --wall LENGTH_M"),
        (["pyramid", "--wall", "0.83", "--out", "w.json"], "or --wall, not both"),
        (["pyramid", "--courses", "2", "--out", "w.json"], "--courses, --out go with --wall"),
        (["--wall", "0.83"], "--wall needs --out FILE"),
    ],
)
def test_the_pattern_command_takes_a_pattern_or_a_wall(
    tmp_path: Path, args: list[str], needle: str
) -> None:
    refused = cli("pattern", *args, cwd=tmp_path)
    assert_clean_error(refused, needle)
    assert list(tmp_path.iterdir()) == []


def test_an_unknown_bond_is_refused_by_name(tmp_path: Path) -> None:
    refused = cli("pattern", "--wall", "0.83", "--bond", "flemish", "--out", "w.json", cwd=tmp_path)
    assert refused.returncode == 2
    assert "'--bond'" in refused.stderr and "'flemish' is not one of" in refused.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_existing_file_is_overwritten_only_with_force(tmp_path: Path) -> None:
    """A run's run.json, say, is not replaced by a wall unless asked for."""
    kept = tmp_path / "run.json"
    kept.write_text('{"method": "agents"}')
    refused = cli("pattern", "--wall", "0.83", "--out", str(kept))
    assert_clean_error(refused, f"--out '{kept}' exists: give --force to overwrite it")
    assert kept.read_text() == '{"method": "agents"}'
    written = cli("pattern", "--wall", "0.83", "--out", str(kept), "--force")
    assert written.returncode == 0, written.stderr
    assert load_pattern(kept, SPEC).name == "run"
    refused = cli("pattern", "pyramid", "--force")
    assert_clean_error(refused, "--force go with --wall")


def test_a_file_name_of_255_bytes_is_written(tmp_path: Path) -> None:
    """The longest name a file may have: the temporary name beside it is short."""
    name = "w" * 250 + ".yaml"
    written = cli("pattern", "--wall", "0.83", "--out", name, cwd=tmp_path)
    assert written.returncode == 0, written.stderr
    assert [path.name for path in tmp_path.iterdir()] == [name]
    assert len(load_pattern(tmp_path / name, SPEC).targets) == 13


def test_a_write_that_fails_leaves_no_file(tmp_path: Path) -> None:
    """A file size limit fails the write as a full disk does: one line naming the file, and
    no temporary file left beside it (there used to be a hidden empty one)."""

    def limited() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (64, 64))

    run = subprocess.run(
        [sys.executable, "-m", "actionreasoning", "pattern", "--wall", "0.83", "--out", "w.json"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        preexec_fn=limited,
        timeout=120,
    )
    assert_clean_error(run, "w.json: cannot write pattern file (File too large)")
    assert list(tmp_path.iterdir()) == []
