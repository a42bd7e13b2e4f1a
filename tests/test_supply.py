"""Brick supplies: a pallet's stacks (the top brick free, the ones under it covered), a
feeder (one brick at a time, the next fed once the last is carried away), each refused
when it cannot hold the pattern's bricks, and each built from by the agents."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from conftest import cli

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.view import Scope, StateView
from actionreasoning.errors import PatternError
from actionreasoning.sim.scene import FEED_CLEAR_M, FEED_TICKS
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial, trial_world
from actionreasoning.world.models import BrickStatus, GoalPattern, Supply
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, SceneSpec
from actionreasoning.world.supply import (
    FEEDER_CAPACITY,
    PALLET_LAYERS,
    PALLET_STACKS,
    feeder_pose,
    lay_out,
)
from actionreasoning.world.walls import Bond, wall_length_m, wall_pattern

SPEC = SceneSpec()
HEIGHT = BRICK_CATALOGUE["full"][2]


def write_row(path: Path, supply: str, sizes: list[str], courses: int = 1) -> Path:
    """Rows of bricks of ``sizes`` (catalogue names) 2 cm apart, ``courses`` high, stacked
    brick over brick, from ``supply``."""
    lengths = [BRICK_CATALOGUE[name][0] for name in sizes]
    span = sum(lengths) + 0.02 * (len(sizes) - 1)
    bricks, x = [], -span / 2.0
    for name, length in zip(sizes, lengths, strict=True):
        bricks.append((name, x + length / 2.0))
        x += length + 0.02
    entries = [
        {"position": [centre, 0.0, (k + 0.5) * HEIGHT], "size": name}
        for k in range(courses)
        for name, centre in bricks
    ]
    data = {"name": path.stem, "brick_size": "full", "supply": supply, "bricks": entries}
    path.write_text(json.dumps(data))
    return path


def bricks_of(goal: GoalPattern) -> list[tuple[float, float, float]]:
    return [t.size_m for t in goal.targets]


def test_a_pallet_holds_its_bricks_in_layers_the_builds_first_on_top(tmp_path: Path) -> None:
    goal = load_pattern(write_row(tmp_path / "p.json", "pallet", ["full"] * 4, courses=3), SPEC)
    sizes = bricks_of(goal)
    for seed in range(20):
        layout = lay_out(
            Supply.PALLET, sizes, [s[2] for s in sizes], SPEC, np.random.default_rng(seed)
        )
        assert layout == lay_out(
            Supply.PALLET, sizes, [s[2] for s in sizes], SPEC, np.random.default_rng(seed)
        )
        stacks: dict[tuple[float, float], list[tuple[float, int]]] = {}
        for brick, pose in enumerate(layout.poses):
            x, y, z = pose.position_m
            layer = (z - HEIGHT / 2.0) / HEIGHT
            assert layer == pytest.approx(round(layer)) and 0 <= round(layer) < PALLET_LAYERS
            radius = math.hypot(x, y)
            assert SPEC.pick_radius_m[0] <= radius <= SPEC.pick_radius_m[1] + 0.005
            key = next((k for k in stacks if math.dist(k, (x, y)) < 0.05), (x, y))
            stacks.setdefault(key, []).append((z, brick))
        assert len(stacks) <= PALLET_STACKS
        for stack in stacks.values():  # lower in the stack: later in the build
            ids = [brick for _, brick in sorted(stack)]
            assert ids == sorted(ids, reverse=True)


def test_two_half_bricks_share_a_cell_end_to_end() -> None:
    half = BRICK_CATALOGUE["half"]
    sizes = [half, half]
    (a, b) = lay_out(Supply.PALLET, sizes, [HEIGHT, HEIGHT], SPEC, np.random.default_rng(1)).poses
    gap = math.dist(a.position_m, b.position_m) - half[0]
    assert gap == pytest.approx(BRICK_CATALOGUE["full"][0] - 2 * half[0], abs=0.005)
    assert a.position_m[2] == b.position_m[2] == HEIGHT / 2.0


@pytest.mark.parametrize(
    ("supply", "full_bricks", "courses", "message"),
    [
        (
            "pallet",
            5,
            4,
            "22 bricks take 20 pallet cells (a full brick or two half bricks each), "
            "but a pallet holds 18 (6 stacks of 3 layers)",
        ),
        ("feeder", 5, 7, f"38 bricks, but the feeder's queue holds {FEEDER_CAPACITY}"),
        ("scattered", 4, 3, "13 bricks, but the pick area holds at most 12 bricks"),
    ],
)
def test_a_supply_too_small_for_the_pattern_is_refused_in_one_line(
    tmp_path: Path, supply: str, full_bricks: int, courses: int, message: str
) -> None:
    path = tmp_path / "wall.json"
    wall = wall_pattern(wall_length_m(full_bricks), courses, Bond.RUNNING, supply=Supply(supply))
    path.write_text(wall.model_dump_json())
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    text = str(info.value)
    assert "\n" not in text and text.startswith(f"{path}: bricks: {message}")


def test_a_pallet_refuses_bricks_not_of_the_catalogue(tmp_path: Path) -> None:
    path = tmp_path / "odd.json"
    path.write_text(
        json.dumps(
            {
                "name": "odd",
                "brick_size": [0.21, 0.1, 0.06],
                "supply": "pallet",
                "bricks": [{"position": [0, 0, 0.03]}],
            }
        )
    )
    with pytest.raises(
        PatternError, match=r"odd.json: bricks: a pallet holds catalogue bricks only"
    ):
        load_pattern(path, SPEC)


def test_an_unknown_supply_is_refused_naming_the_field(tmp_path: Path) -> None:
    path = tmp_path / "crane.json"
    path.write_text(
        json.dumps(
            {
                "name": "c",
                "brick_size": "full",
                "supply": "crane",
                "bricks": [{"position": [0, 0, 0.03]}],
            }
        )
    )
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    assert (
        "supply" in str(info.value) and "pallet" in str(info.value) and "\n" not in str(info.value)
    )


def spec_of(goal: GoalPattern, name: str) -> TrialSpec:
    return TrialSpec(method=Method.AGENTS, pattern_name=name, goal=goal, run_seed=2, trial=0)


def test_only_a_stacks_top_brick_is_free_and_the_one_under_it_is_freed_when_it_is_taken(
    tmp_path: Path,
) -> None:
    goal = load_pattern(write_row(tmp_path / "p.json", "pallet", ["full"] * 4, courses=3), SPEC)
    with trial_world(spec_of(goal, "p")) as world:
        state = world.sensor.perceive(goal)
        status = {b.id: b.status for b in state.bricks}
        assert [i for i, s in status.items() if s is BrickStatus.IN_PICK_AREA] == list(range(6))
        assert all(status[i] is BrickStatus.COVERED for i in range(6, 12))
        assert {b.id for b in state.bricks if b.pickable} == set(range(6))
        # Carry brick 0 away (as a grasp and a lift would), and what lay under it is free.
        under = next(
            b.id
            for b in state.bricks
            if b.id >= 6
            and math.dist(b.pose.position_m[:2], state.brick(0).pose.position_m[:2]) < 0.01
        )
        scene = world.scene
        p.resetBasePositionAndOrientation(
            scene.bricks[0], (0.6, 0.3, 0.03), (0, 0, 0, 1), physicsClientId=scene.client
        )
        scene.step(scene.ticks_for(0.1))
        after = world.sensor.perceive(goal)
        assert after.brick(under).status is BrickStatus.IN_PICK_AREA and after.brick(under).pickable


def test_a_feeder_feeds_the_next_brick_once_the_last_is_carried_away(tmp_path: Path) -> None:
    goal = load_pattern(write_row(tmp_path / "f.json", "feeder", ["full", "half", "full"]), SPEC)
    with trial_world(spec_of(goal, "f")) as world:
        scene, sensor = world.scene, world.sensor
        state = sensor.perceive(goal)
        assert [b.status for b in state.bricks] == [
            BrickStatus.IN_PICK_AREA,
            BrickStatus.QUEUED,
            BrickStatus.QUEUED,
        ]
        feed = feeder_pose().position_m
        assert math.dist(state.brick(0).pose.position_m[:2], feed[:2]) < 1e-3
        view = StateView.of(state, TaskMemory(), Scope.PICK)
        assert [b.id for b in view.bricks] == [0] and view.supply is Supply.FEEDER
        # Moved a little, it is still at the feeder: nothing is fed.
        near = (feed[0] + FEED_CLEAR_M / 2, feed[1], HEIGHT / 2)
        p.resetBasePositionAndOrientation(
            scene.bricks[0], near, (0, 0, 0, 1), physicsClientId=scene.client
        )
        scene.step(2 * FEED_TICKS)
        assert sensor.perceive(goal).brick(1).status is BrickStatus.QUEUED
        # Carried away: the half brick is fed, and lies at the feeder at its own height.
        p.resetBasePositionAndOrientation(
            scene.bricks[0], (0.6, 0.3, 0.03), (0, 0, 0, 1), physicsClientId=scene.client
        )
        scene.step(2 * FEED_TICKS)
        fed = sensor.perceive(goal)
        assert [b.status for b in fed.bricks][1:] == [BrickStatus.IN_PICK_AREA, BrickStatus.QUEUED]
        x, y, z = fed.brick(1).pose.position_m
        assert math.dist((x, y), feed[:2]) < 1e-3 and z == pytest.approx(
            BRICK_CATALOGUE["half"][2] / 2, abs=1e-3
        )


@pytest.mark.slow
@pytest.mark.parametrize("supply", ["pallet", "feeder"])
def test_the_agents_build_from_each_supply_and_each_brick_is_scored_at_its_size(
    tmp_path: Path, supply: str
) -> None:
    goal = load_pattern(
        write_row(tmp_path / f"{supply}.json", supply, ["half", "full", "half"]), SPEC
    )
    spec = TrialSpec(
        method=Method.AGENTS,
        pattern_name=supply,
        goal=goal,
        run_seed=4,
        trial=0,
        config=TrialConfig(),
    )
    result = run_trial(spec).result
    assert result.success, result.failure
    assert [tuple(b.size) for b in result.bricks] == [
        BRICK_CATALOGUE["half"],
        BRICK_CATALOGUE["full"],
        BRICK_CATALOGUE["half"],
    ]
    assert all(b.center_offset_cm < 2.0 and b.iou > 0.8 for b in result.bricks)


@pytest.mark.slow
def test_eval_records_the_supply_in_run_json_and_the_classical_script_builds_from_a_feeder(
    tmp_path: Path,
) -> None:
    pattern = write_row(tmp_path / "f.json", "feeder", ["full", "half"])
    out = tmp_path / "run"
    done = cli(
        "eval",
        "--method",
        "classical",
        "--pattern",
        str(pattern),
        "--trials",
        "1",
        "--out",
        str(out),
    )
    assert done.returncode == 0, done.stderr
    assert json.loads((out / "run.json").read_text())["supply"] == "feeder"
    (line,) = (out / "results.jsonl").read_text().splitlines()
    bricks = json.loads(line)["bricks"]
    assert [b["size"] for b in bricks] == [
        list(BRICK_CATALOGUE["full"]),
        list(BRICK_CATALOGUE["half"]),
    ]
    # Both were fed and carried to the build area: neither is still at the feeder.
    feed = feeder_pose().position_m
    assert all(math.dist(b["final_position"][:2], feed[:2]) > 0.3 for b in bricks)
