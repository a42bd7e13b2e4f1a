"""WorldState: measured from the simulator, JSON round trip, JSON schema."""

from __future__ import annotations

import json

import numpy as np

from actionreasoning.sim.perceive import Sensor
from actionreasoning.sim.scene import Scene
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import BrickState, Pose, Progress, WorldState
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec


def test_round_trip_of_a_measured_state(scene: Scene) -> None:
    scene.step(30)
    goal = load_pattern("pyramid", scene.spec)
    sensor = Sensor(scene, NOISE["none"], trial_seed=0)
    state = sensor.perceive(goal, Progress(placed_ids=(), current_brick=0, step="pre_grasp"))
    text = state.model_dump_json()
    again = WorldState.model_validate_json(text)
    assert again == state
    assert json.loads(again.model_dump_json()) == json.loads(text)
    assert len(state.bricks) == 6
    assert all(b.status == "in_pick_area" for b in state.bricks)
    assert state.robot.gripper_width_m > 0.14  # starts open
    assert state.goal.targets[5].pose.position_m[2] > state.goal.targets[0].pose.position_m[2]


def test_json_schema_describes_every_part() -> None:
    schema = WorldState.model_json_schema()
    assert set(schema["required"]) >= {"time_s", "robot", "bricks", "goal"}
    for part in ("Pose", "RobotState", "PadContact", "BrickState", "GoalPattern", "Progress"):
        assert part in schema["$defs"]
    assert schema["$defs"]["BrickState"]["properties"]["status"]["$ref"] == "#/$defs/BrickStatus"
    statuses = schema["$defs"]["BrickStatus"]["enum"]
    assert statuses == [
        "in_pick_area",
        "grasped",
        "placed",
        "dropped",
        "toppled",
        "covered",
        "queued",
    ]


def test_layout_is_deterministic_spaced_and_reachable() -> None:
    spec = SceneSpec()
    for seed in range(50):
        poses = sample_pick_poses(np.random.default_rng(seed), 6, spec)
        assert poses == sample_pick_poses(np.random.default_rng(seed), 6, spec)
        centres = np.array([p.position_m[:2] for p in poses])
        gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + np.eye(6)
        assert gaps.min() >= spec.pick_min_spacing_m
        assert all(spec.reach.contains(*p.position_m) for p in poses)


def test_a_dropped_brick_lying_flat_can_be_picked_on_the_ground_or_on_other_bricks() -> None:
    size = (0.20, 0.095, 0.06)

    def brick(z: float, status: str) -> BrickState:
        pose = Pose(position_m=(0.5, 0.1, z), quat_xyzw=(0.0, 0.0, 0.0, 1.0))
        return BrickState(id=0, size_m=size, mass_kg=1.5, friction=0.5, pose=pose, status=status)

    assert brick(0.03, "in_pick_area").pickable
    assert brick(0.03, "dropped").pickable
    assert brick(0.09, "dropped").pickable  # fell flat onto other bricks: picked off them
    assert not brick(0.05, "toppled").pickable
    assert not brick(0.03, "placed").pickable
    assert not brick(0.30, "grasped").pickable
