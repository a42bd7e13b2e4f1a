"""A pattern's brick size is the size the scene spawns, the robot senses and the score uses;
sizes the gripper cannot hold are refused up front."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pybullet as p
import pytest
from conftest import assert_clean_error, cli

from actionreasoning.errors import PatternError
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialSpec, run_trial, trial_world
from actionreasoning.world.patterns import GRIP_MARGIN_M, brick_size_limits, load_pattern
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, GRIPPER_GAP_M, SceneSpec
from actionreasoning.world.stages import StageEvent
from actionreasoning.world.tolerances import Tolerances

SPEC = SceneSpec()
#: The issue's bricks: 20 % larger on every edge than the catalogue's.
SIZE = (0.24, 0.115, 0.071)
CATALOGUE_DENSITY = SPEC.brick_mass_kg / math.prod(SPEC.brick_size_m)
#: The widest brick allowed, and a millimetre wider.
WIDEST_M = brick_size_limits(SPEC)[1][1]
TOO_WIDE_M = round(WIDEST_M + 0.001, 4)


def write_pattern(path: Path, size: tuple[float, ...], count: int = 2) -> Path:
    """``count`` bricks of ``size`` side by side on the ground in the build area."""
    pitch = size[0] + 0.03
    bricks = [
        {"position": [(i - (count - 1) / 2) * pitch, 0.0, size[2] / 2], "yaw_deg": 0}
        for i in range(count)
    ]
    path.write_text(json.dumps({"name": "big", "brick_size": list(size), "bricks": bricks}))
    return path


def spawned_size(scene: Scene, brick: int) -> tuple[float, ...]:
    """The box PyBullet collides with for ``brick``: its full edge lengths."""
    (shape,) = p.getCollisionShapeData(scene.bricks[brick], -1, physicsClientId=scene.client)
    assert shape[2] == p.GEOM_BOX
    return tuple(shape[3])


def spawned_mass(scene: Scene, brick: int) -> float:
    return p.getDynamicsInfo(scene.bricks[brick], -1, physicsClientId=scene.client)[0]


@pytest.mark.slow
def test_the_classical_script_builds_a_pattern_of_other_bricks_with_those_bricks(
    tmp_path: Path,
) -> None:
    goal = load_pattern(write_pattern(tmp_path / "big.json", SIZE), SPEC)
    spec = TrialSpec(
        method=Method.CLASSICAL, pattern_name="big", goal=goal, run_seed=0, trial=0,
        config=TrialConfig(physics=PRECISE),
    )  # fmt: skip
    seen: dict[int, tuple[tuple[float, ...], float]] = {}

    class Look(TrialObserver):
        def stage(self, scene: Scene, event: StageEvent) -> None:
            for brick in range(len(scene.bricks)):
                seen[brick] = spawned_size(scene, brick), spawned_mass(scene, brick)

    result = run_trial(spec, [Look()]).result
    assert set(seen) == {0, 1}
    for size, mass in seen.values():
        assert size == pytest.approx(SIZE, abs=1e-9)
        assert mass == pytest.approx(CATALOGUE_DENSITY * math.prod(SIZE))
    for brick in result.bricks:
        assert brick.size == pytest.approx(SIZE, abs=1e-9)  # the score's box is the spawned one
    assert result.success, result.failure
    # Spawned at the catalogue's 0.20 x 0.095 x 0.06 m, the same build scored 85.5 % here.
    assert result.metrics.iou > 0.99


def test_the_robot_senses_the_patterns_brick_size_and_its_mass(tmp_path: Path) -> None:
    goal = load_pattern(write_pattern(tmp_path / "big.json", SIZE, count=1), SPEC)
    spec = TrialSpec(method=Method.AGENTS, pattern_name="big", goal=goal, run_seed=3, trial=1)
    with trial_world(spec) as world:
        (brick,) = world.sensor.perceive(goal).bricks
        (laid_out,) = world.scene.bricks
        height = p.getBasePositionAndOrientation(laid_out, physicsClientId=world.scene.client)
    assert brick.size_m == SIZE
    assert brick.mass_kg == pytest.approx(CATALOGUE_DENSITY * math.prod(SIZE))
    assert height[0][2] == pytest.approx(SIZE[2] / 2, abs=2e-3)  # it lies on the ground


def test_the_catalogue_brick_keeps_its_mass_exactly() -> None:
    body = SPEC.brick_body(0.5, SPEC.brick_size_m)
    assert (body.size_m, body.mass_kg) == (SPEC.brick_size_m, SPEC.brick_mass_kg)


@pytest.mark.parametrize(
    ("size", "field"),
    [
        ((1e6, 0.095, 0.06), "brick_size[0]: length 1e+06 m"),
        ((0.04, 0.095, 0.06), "brick_size[0]: length 0.04 m"),
        ((0.2, 0.2, 0.06), "brick_size[1]: width (across the gripper) 0.2 m"),
        ((0.2, TOO_WIDE_M, 0.06), f"brick_size[1]: width (across the gripper) {TOO_WIDE_M:g} m"),
        ((0.2, 0.05, 0.06), "brick_size[1]: width (across the gripper) 0.05 m"),
        ((0.2, 0.095, 0.03), "brick_size[2]: height 0.03 m"),
        ((0.2, 0.095, 0.2), "brick_size[2]: height 0.2 m"),
    ],
)
def test_a_brick_the_gripper_cannot_hold_is_refused_naming_the_field(
    tmp_path: Path, size: tuple[float, float, float], field: str
) -> None:
    path = write_pattern(tmp_path / "odd.json", size, count=1)
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    message = str(info.value)
    assert message.startswith(f"{path}: {field} is outside "), message
    assert "gripper opens 0.06-0.16 m" in message and "\n" not in message


def test_the_pattern_command_refuses_an_absurd_brick(tmp_path: Path) -> None:
    path = write_pattern(tmp_path / "huge.json", (1e6, 0.095, 0.06), count=1)
    assert_clean_error(cli("pattern", str(path)), "huge.json", "brick_size[0]", "outside")


def test_the_widest_brick_allowed_loads_and_leaves_the_pads_room_to_pass_it(
    tmp_path: Path,
) -> None:
    """sigma_2 asks the opening to pass the brick by delta: the widest brick allowed leaves
    that and a margin within the gripper's full opening."""
    assert WIDEST_M <= GRIPPER_GAP_M[1] - Tolerances().delta_m - GRIP_MARGIN_M
    size = (0.2, math.floor(WIDEST_M * 1e4) / 1e4, 0.06)
    assert load_pattern(write_pattern(tmp_path / "wide.json", size), SPEC).brick_size_m == size


@pytest.mark.parametrize("size", [(0.1, 0.07, 0.045), (0.3, 0.12, 0.085)])
def test_the_extreme_sizes_still_allowed_load(tmp_path: Path, size: tuple[float, ...]) -> None:
    goal = load_pattern(write_pattern(tmp_path / "edge.json", size), SPEC)
    assert goal.brick_size_m == size


def write_mixed(path: Path, sizes: list[object]) -> Path:
    """One course of bricks on the ground, each of its own ``size`` (edges or a catalogue
    name; None: the pattern's full brick), 2 cm apart."""
    edges = [
        BRICK_CATALOGUE[s] if isinstance(s, str) else (s or BRICK_CATALOGUE["full"]) for s in sizes
    ]
    centres, x = [], 0.0
    for size in edges:
        centres.append(x + size[0] / 2)
        x += size[0] + 0.02
    bricks = [
        {"position": [c - x / 2, 0.0, size[2] / 2], **({"size": s} if s is not None else {})}
        for c, size, s in zip(centres, edges, sizes, strict=True)
    ]
    path.write_text(json.dumps({"name": "mixed", "brick_size": "full", "bricks": bricks}))
    return path


def test_each_brick_of_a_pattern_has_its_own_size_or_a_catalogue_name(tmp_path: Path) -> None:
    goal = load_pattern(write_mixed(tmp_path / "m.json", ["half", None, [0.2, 0.1, 0.065]]), SPEC)
    assert [t.size_m for t in goal.targets] == [
        BRICK_CATALOGUE["half"],
        BRICK_CATALOGUE["full"],
        (0.2, 0.1, 0.065),
    ]
    assert goal.brick_size_m == BRICK_CATALOGUE["full"]


def test_a_brick_of_a_size_outside_the_limits_is_refused_naming_its_entry(tmp_path: Path) -> None:
    path = write_mixed(tmp_path / "m.json", [None, [0.2, 0.2, 0.06]])
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    assert str(info.value).startswith(f"{path}: bricks[1].size[1]: width (across the gripper)")


def test_an_unknown_catalogue_name_is_refused_in_one_line(tmp_path: Path) -> None:
    path = write_mixed(tmp_path / "m.json", [None])
    data = json.loads(path.read_text())
    data["bricks"][0]["size"] = "quarter"
    path.write_text(json.dumps(data))
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    message = str(info.value)
    assert (
        message == f"{path}: bricks[0].size: unknown brick 'quarter' (the catalogue's: full, half)"
    )


@pytest.mark.slow
def test_a_half_brick_is_spawned_at_its_size_with_its_catalogue_mass(tmp_path: Path) -> None:
    goal = load_pattern(write_mixed(tmp_path / "m.json", ["half", "full"]), SPEC)
    spec = TrialSpec(method=Method.AGENTS, pattern_name="mixed", goal=goal, run_seed=3, trial=0)
    with trial_world(spec) as world:
        half, full = world.sensor.perceive(goal).bricks
        spawned = [spawned_size(world.scene, b) for b in range(2)]
        masses = [spawned_mass(world.scene, b) for b in range(2)]
    assert (half.size_m, full.size_m) == (BRICK_CATALOGUE["half"], BRICK_CATALOGUE["full"])
    for size, name in zip(spawned, ("half", "full"), strict=True):
        assert size == pytest.approx(BRICK_CATALOGUE[name])
    assert half.mass_kg == pytest.approx(CATALOGUE_DENSITY * math.prod(BRICK_CATALOGUE["half"]))
    assert masses == pytest.approx([half.mass_kg, full.mass_kg])
    assert full.mass_kg == SPEC.brick_mass_kg
