"""Putting a brick down for a re-grasp, in the real simulator: a brick rolled in the hand
is pressed flat, not let go on a corner."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from conftest import SMALL_PATTERN
from scipy.spatial.transform import Rotation

from actionreasoning.agents.calls import AgentCaller, BuildResult
from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.agents.put_down import PutDown
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.geometry import quat_yaw, tilt_deg, top_down_quat
from actionreasoning.world.models import Pose, Progress
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, SceneSpec
from actionreasoning.world.tolerances import Tolerances


@pytest.mark.slow
@pytest.mark.parametrize(
    ("size", "roll_deg"),
    [
        ("full", -35.0),
        ("full", 50.0),
        # Past atan(length / height), 58 deg: pressed down it would tip onto its end, so it
        # is laid level with the tool tilted by its roll.
        ("half", 68.0),
    ],
)
def test_a_brick_rolled_in_the_hand_is_pressed_flat_onto_its_spot(
    tmp_path: Path, size: str, roll_deg: float
) -> None:
    path = tmp_path / "small.json"
    one = {"brick_size": BRICK_CATALOGUE[size], "bricks": SMALL_PATTERN["bricks"][:1]}
    path.write_text(json.dumps(SMALL_PATTERN | one))
    goal = load_pattern(path, SceneSpec())
    spec = TrialSpec(
        method=Method.AGENTS, pattern_name="one", goal=goal, run_seed=2, trial=0,
        config=TrialConfig(physics=PRECISE),
    )  # fmt: skip
    with trial_world(spec) as made:
        scene = made.scene
        world = SimWorld(WaypointController(scene, made.arm), goal, made.sensor)
        centre, quat = scene.brick_pose(0)
        tool_quat = top_down_quat(quat_yaw(quat))
        grasp = Pose(position_m=(centre[0], centre[1], centre[2]), quat_xyzw=tool_quat)
        world.move(WaypointProposal(position_m=(*centre[:2], 0.15), quat_xyzw=tool_quat))
        world.grip(0.14)
        world.move(WaypointProposal(position_m=centre, quat_xyzw=tool_quat, path="linear"))
        world.grip(None)
        world.move(WaypointProposal(position_m=(*centre[:2], 0.25), quat_xyzw=tool_quat))
        # Roll the brick in the hand about the axis between the pads, through the tool centre
        # point, as a lift under paper physics does.
        tcp, tcp_quat = scene.tcp_pose()
        roll = Rotation.from_rotvec(
            Rotation.from_quat(tcp_quat).apply((0.0, 1.0, 0.0)) * math.radians(roll_deg)
        )
        brick_centre, brick_quat = scene.brick_pose(0)
        rolled = roll.apply(np.subtract(brick_centre, tcp)) + tcp
        turned = (roll * Rotation.from_quat(brick_quat)).as_quat()
        p.resetBasePositionAndOrientation(
            scene.bricks[0], rolled.tolist(), turned.tolist(), physicsClientId=scene.client
        )
        scene.step(scene.ticks_for(0.3))
        assert scene.is_held(0)
        # Rolled far past eps_tilt: let go as it is, it would come down on an edge.
        assert tilt_deg(scene.brick_pose(0)[1]) > 20.0

        calls = AgentCaller(world, BuiltinReasoner(), Tolerances(), BuildResult())
        observe = lambda: world.observe(Progress(current_brick=0, step="lift"))  # noqa: E731
        PutDown(world, calls).put_back(observe, 0, grasp, height=0.25)

        scene.step(scene.ticks_for(0.5))
        landed, landed_quat = scene.brick_pose(0)
        assert not scene.is_held(0)
        assert tilt_deg(landed_quat) < 2.0
        assert math.dist(landed[:2], grasp.position_m[:2]) < 0.02
