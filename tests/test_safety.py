"""Safety limits and budgets, independent of any reasoner: a violating waypoint is refused
before the arm moves; a trial out of steps or time, or whose physics blew up, ends with a
reason instead of hanging or crashing."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pybullet as p
import pytest
from conftest import SMALL_PATTERN, layout_scene

from actionreasoning.control.safety import SafetyLimits
from actionreasoning.control.waypoint import MIN_JERK_PEAK, Waypoint, WaypointController
from actionreasoning.errors import TrialAborted
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.geometry import top_down_quat
from actionreasoning.world.models import READY_POSE, Pose
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import WORKSPACE, SceneSpec, WorkspaceBox


def refused(controller: WaypointController, waypoint: Waypoint, needle: str) -> None:
    """The waypoint is refused with ``needle`` in the reason, and nothing moved."""
    ticks, joints = controller.scene.ticks, controller.scene.arm_targets.copy()
    with pytest.raises(TrialAborted) as error:
        controller.execute(waypoint)
    assert error.value.reason == "safety_limit" and needle in error.value.detail
    assert controller.scene.ticks == ticks and np.array_equal(controller.scene.arm_targets, joints)


def at(x: float, y: float, z: float) -> Pose:
    return Pose(position_m=(x, y, z), quat_xyzw=top_down_quat(math.atan2(y, x)))


LOW_BOX = WorkspaceBox(high_m=(0.9, 0.9, 0.35))


@pytest.mark.parametrize(
    ("workspace", "pose", "needle"),
    [
        (LOW_BOX, READY_POSE, "would leave the workspace box at (0.450, -0.250, 0.400) m"),
        (
            WORKSPACE,
            at(0.5, 0.2, 0.005),
            "down to 0.005 m at (0.500, 0.200, 0.005) m, below the 0.02 m minimum height",
        ),
    ],
)
def test_a_waypoint_outside_the_envelope_is_refused(
    arm: KinematicArm, workspace: WorkspaceBox, pose: Pose, needle: str
) -> None:
    """The workspace box is the scene's."""
    scene = layout_scene(arm, SceneSpec(workspace=workspace))
    try:
        refused(WaypointController(scene, arm), Waypoint(pose=pose), needle)
    finally:
        scene.close()


def test_a_move_faster_than_the_tool_speed_limit_is_refused(
    scene: Scene, arm: KinematicArm
) -> None:
    fast = Waypoint(pose=at(0.45, -0.25, 0.10), path="linear", ticks=20)  # 0.3 m in 42 ms
    refused(WaypointController(scene, arm), fast, "above the 2.5 m/s limit")


def test_a_free_move_with_no_duration_keeps_the_tool_speed_limit(
    scene: Scene, arm: KinematicArm
) -> None:
    """Its least duration keeps the tool within the envelope, not only the joints' speed: a
    sweep far from the base, whose joints turn slowly, is slowed instead of refused."""
    safety = SafetyLimits(max_tcp_speed_mps=0.5)
    controller = WaypointController(scene, arm, safety=safety)
    controller.execute(Waypoint(pose=at(0.6, -0.3, 0.20)))
    sweep = Waypoint(pose=at(0.6, 0.3, 0.20))
    knots = controller.plan(sweep)
    joint_ticks = scene.ticks_for(
        MIN_JERK_PEAK * float(np.max(np.abs(knots[-1] - knots[0]))) / 2.5
    )  # the joints' own limit alone
    start, end = (arm.forward(q)[0] for q in knots)
    with pytest.raises(TrialAborted, match=r"above the 0\.5 m/s limit"):
        controller.execute(sweep.model_copy(update={"ticks": joint_ticks}))
    motion = controller.execute(sweep)
    assert motion.converged and motion.position_error_m < 2e-3
    seconds = motion.ticks * scene.physics.time_step_s
    assert MIN_JERK_PEAK * math.dist(start, end) / seconds <= 0.5


def test_a_free_move_low_across_a_brick_is_refused_in_transit(
    scene: Scene, arm: KinematicArm
) -> None:
    controller = WaypointController(scene, arm)
    (x, y, _), _ = scene.brick_pose(0)
    radius, azimuth = math.hypot(x, y), math.atan2(y, x)
    side = [(radius * math.cos(azimuth + s), radius * math.sin(azimuth + s)) for s in (0.4, -0.4)]
    controller.execute(Waypoint(pose=at(*side[0], 0.30)))
    controller.execute(Waypoint(pose=at(*side[0], 0.09), path="linear"))
    refused(controller, Waypoint(pose=at(*side[1], 0.09)), "in transit the tool would pass")
    controller.execute(Waypoint(pose=at(*side[1], 0.30)))  # high above it: allowed


def test_a_brick_flung_away_is_a_physics_blowup(scene: Scene, arm: KinematicArm) -> None:
    p.resetBaseVelocity(scene.bricks[2], [0.0, 0.0, 400.0], physicsClientId=scene.client)
    controller = WaypointController(scene, arm)
    with pytest.raises(TrialAborted) as error:
        controller.execute(Waypoint(pose=at(0.45, -0.25, 0.35)))
    assert error.value.reason == "physics_blowup" and "brick 2 was flung to" in error.value.detail


@pytest.mark.parametrize(
    ("budget", "reason"),
    [
        (TrialBudget(max_steps=600), "step_budget"),  # spent before the first grasp
        (TrialBudget(max_wall_s=1e-9), "time_budget"),
    ],
)
def test_a_trial_out_of_budget_ends_with_its_reason_and_bricks_on_the_table(
    tmp_path: Path, budget: TrialBudget, reason: str
) -> None:
    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    goal = load_pattern(str(path), SceneSpec())
    for method in Method:
        spec = TrialSpec(
            method=method, pattern_name="small", goal=goal, run_seed=0, trial=0,
            config=TrialConfig(budget=budget),
        )  # fmt: skip
        result = run_trial(spec).result
        assert not result.success and result.failure is not None
        assert result.failure.reason == reason, result.failure
        assert all(b["final_position"][2] < 0.05 for b in result.model_dump()["bricks"])
