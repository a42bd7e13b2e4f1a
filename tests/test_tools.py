"""The tool library: hand-built world states in, hand-computed answers out."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from conftest import pick_up

from actionreasoning.agents.schema_text import describe_fields
from actionreasoning.control.classical import ClassicalController
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.errors import ToolError
from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.perceive import Sensor
from actionreasoning.sim.scene import Scene
from actionreasoning.tools.base import ToolContext
from actionreasoning.tools.geometry import GraspQuery, grasp_candidates
from actionreasoning.tools.registry import TOOLS, call_tool
from actionreasoning.world.geometry import top_down_quat, yaw_quat
from actionreasoning.world.models import BrickState, Pose, RobotState, WorldState
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec

SPEC = SceneSpec()
GOAL = load_pattern("pyramid", SPEC)
L, W, H = SPEC.brick_size_m


def world(*poses: Pose) -> WorldState:
    """A world with bricks at ``poses`` (ids in order) and the pyramid as goal."""
    robot = RobotState(
        ee_pose=Pose(position_m=(0.45, 0.0, 0.4), quat_xyzw=top_down_quat(0.0)),
        joint_positions_rad=(0.0,) * 7,
        gripper_width_m=0.16,
        finger_depth_m=0.02,
        finger_forces_n=(0.0, 0.0),
    )
    bricks = tuple(
        BrickState(id=i, size_m=SPEC.brick_size_m, mass_kg=1.5, friction=0.8, pose=pose)
        for i, pose in enumerate(poses)
    )
    return WorldState(time_s=0.0, robot=robot, bricks=bricks, goal=GOAL)


@pytest.fixture(scope="module")
def arm() -> Iterator[KinematicArm]:
    arm = KinematicArm()
    yield arm
    arm.close()


_CHECKERS: dict[int, CollisionChecker] = {}


def context(arm: KinematicArm, state: WorldState) -> ToolContext:
    """A tool context on ``arm``, with one collision checker per arm."""
    if id(arm) not in _CHECKERS:
        _CHECKERS[id(arm)] = CollisionChecker(arm)
    return ToolContext(state=state, arm=arm, collisions=_CHECKERS[id(arm)])


def run(arm: KinematicArm, state: WorldState, name: str, **arguments: object):
    return call_tool(name, arguments, context(arm, state))


def test_every_tool_is_described_for_the_prompts() -> None:
    assert set(TOOLS) == {
        "alignment_errors",
        "grasp_options",
        "held_pose",
        "placement_pose",
        "placement_check",
        "support_contact",
        "reachability",
        "collision_check",
        "finger_contacts",
        "slip_estimate",
        "deproject",
    }
    for name, tool in TOOLS.items():
        assert tool.name == name and tool.description
        for model in (tool.input_model, tool.output_model):
            lines = describe_fields(model)
            described = [line[2:].split(":")[0] for line in lines if line.startswith("- ")]
            assert described == list(model.model_fields)


def test_alignment_of_a_brick_on_its_target_is_zero(arm: KinematicArm) -> None:
    state = world(GOAL.targets[3].pose)
    errors = run(arm, state, "alignment_errors", brick_id=0, target_index=3)
    assert errors.e_xy_norm_m == pytest.approx(0.0, abs=1e-12)
    assert errors.e_theta_deg == pytest.approx(0.0, abs=1e-9)
    assert errors.d_perp_m == pytest.approx(0.0, abs=1e-12)
    assert errors.tilt_deg == pytest.approx(0.0, abs=1e-6)


def test_alignment_of_a_shifted_turned_raised_brick(arm: KinematicArm) -> None:
    target = GOAL.targets[0].pose
    x, y, z = target.position_m
    yaw = SPEC.build_yaw_rad
    moved = Pose(position_m=(x - 0.01, y + 0.02, z + 0.005), quat_xyzw=yaw_quat(yaw - 0.1))
    errors = run(arm, world(moved), "alignment_errors", brick_id=0, target_index=0)
    assert errors.e_xy_m == pytest.approx((0.01, -0.02))
    assert errors.e_xy_norm_m == pytest.approx(math.hypot(0.01, 0.02))
    assert errors.e_theta_deg == pytest.approx(math.degrees(0.1))
    assert errors.d_perp_m == pytest.approx(0.005)


def test_grasp_candidates_close_across_the_short_side(arm: KinematicArm) -> None:
    yaw = math.radians(30.0)
    state = world(Pose(position_m=(0.1, -0.6, H / 2), quat_xyzw=yaw_quat(yaw)))
    query = GraspQuery(brick_id=0, approach_height_m=0.1)
    grasps = grasp_candidates(context(arm, state), query)
    assert grasps.grasp_axis_xy == pytest.approx((-math.sin(yaw), math.cos(yaw)))
    first, second = grasps.candidates
    assert first.gripper_yaw_deg == pytest.approx(30.0)
    assert second.gripper_yaw_deg == pytest.approx(-150.0)
    assert first.grasp_pose.position_m == pytest.approx((0.1, -0.6, H / 2))
    assert first.approach_pose.position_m == pytest.approx((0.1, -0.6, H / 2 + 0.1))
    assert first.opening_needed_m == pytest.approx(W + 0.04)


def test_grasp_options_check_both_grasps_for_pick_and_place(arm: KinematicArm) -> None:
    yaw = math.radians(30.0)
    free = world(Pose(position_m=(0.3, -0.5, H / 2), quat_xyzw=yaw_quat(yaw)))
    first, second = run(arm, free, "grasp_options", brick_id=0, target_index=0).options
    assert {round(first.gripper_yaw_deg), round(second.gripper_yaw_deg)} == {30, -150}
    for option in (first, second):
        assert option.grasp_pose.position_m == pytest.approx((0.3, -0.5, H / 2))
        assert option.approach_pose.position_m[2] == pytest.approx(H / 2 + 0.12)
    usable = [o for o in (first, second) if o.reachable]
    assert usable and all(o.approach_clearance_m > 0.02 for o in usable)
    assert all(o.descent_clearance_m > 0.0 for o in usable)
    assert all(o.wrist_deg is not None and 0.0 <= o.wrist_deg <= 180.0 for o in usable)
    # A second brick 12 cm to the side: the open fingers come down on it.
    beside = Pose(position_m=(0.3 + 0.06, -0.5 - 0.104, H / 2), quat_xyzw=yaw_quat(yaw))
    crowded = world(free.bricks[0].pose, beside)
    options = run(arm, crowded, "grasp_options", brick_id=0, target_index=0).options
    assert all(o.descent_clearance_m < 0.0 for o in options)


def test_grasp_options_out_of_reach_measure_no_wrist_turn(arm: KinematicArm) -> None:
    far = world(Pose(position_m=(1.5, 0.0, H / 2)))
    options = run(arm, far, "grasp_options", brick_id=0, target_index=0).options
    assert all(not o.reachable and o.wrist_deg is None for o in options)
    assert '"wrist_deg":null' in options[0].model_dump_json()  # what a model reads


def test_support_on_the_ground_and_on_two_bricks(arm: KinematicArm) -> None:
    state = world(*(t.pose for t in GOAL.targets[:4]))
    ground = run(arm, state, "support_contact", brick_id=0)
    assert ground.on_ground and ground.carriers == () and ground.centre_supported
    upper = run(arm, state, "support_contact", brick_id=3)
    assert not upper.on_ground
    assert upper.carriers == (0, 1)
    assert upper.centre_supported
    # Each lower brick carries (L - gap) / 2 of the upper brick's length.
    assert upper.contact_area_m2 == pytest.approx(2 * (L - 0.05) / 2 * W, rel=1e-6)


def test_support_finds_a_floating_and_an_overhanging_brick(arm: KinematicArm) -> None:
    base = Pose(position_m=(0.0, -0.6, H / 2), quat_xyzw=yaw_quat(0.0))
    floating = Pose(position_m=(0.3, -0.6, 1.5 * H), quat_xyzw=yaw_quat(0.0))
    overhang = Pose(position_m=(0.16, -0.6, 1.5 * H), quat_xyzw=yaw_quat(0.0))
    state = world(base, floating, overhang)
    lost = run(arm, state, "support_contact", brick_id=1)
    assert lost.carriers == () and not lost.on_ground and not lost.centre_supported
    tipping = run(arm, state, "support_contact", brick_id=2)
    assert tipping.carriers == (0,) and not tipping.centre_supported


def test_reachability_inside_and_outside_the_band(arm: KinematicArm) -> None:
    state = world()
    near = Pose(position_m=(0.55, 0.2, 0.2), quat_xyzw=top_down_quat(0.3))
    report = run(arm, state, "reachability", pose=near.model_dump())
    assert report.reachable and report.position_error_m < 1e-4 and len(report.joints_rad) == 7
    far = Pose(position_m=(1.2, 0.0, 0.2), quat_xyzw=top_down_quat(0.0))
    report = run(arm, state, "reachability", pose=far.model_dump())
    assert not report.reachable and report.position_error_m > 0.1


@pytest.mark.parametrize(
    ("name", "arguments", "message"),
    [
        ("support_contact", {"brick_id": 9}, "no brick with id 9"),
        ("alignment_errors", {"brick_id": 0, "target_index": 6}, "no target 6"),
        ("support_contact", {"brick_id": "zero"}, "support_contact: brick_id:"),
        ("support_contact", {"brick_id": 0, "extra": 1}, "extra"),
        ("__import__('os').system", {}, "unknown tool"),
        # Numbers the arm model cannot take: its IK hangs on 1e308, fails on a zero quaternion.
        ("reachability", {"pose": {"position_m": [1e308, 0.0, 0.3]}}, "more than 100 m away"),
        ("reachability", {"pose": {"position_m": ["NaN", 0.0, 0.3]}}, "nan is not a finite"),
        (
            "collision_check",
            {"pose": {"position_m": [0.5, 0.0, 0.3]}, "start_pose": {"position_m": [0, -101, 0]}},
            "collision_check.start_pose.position_m is more than 100 m away",
        ),
        (
            "collision_check",
            {"pose": {"position_m": [0.5, 0.0, 0.3], "quat_xyzw": [0, 0, 0, 0]}},
            "norm 0: give a unit quaternion",
        ),
        (
            "grasp_options",
            {"brick_id": 0, "target_index": 0, "descent_opening_m": float("inf")},
            "descent_opening_m",
        ),
    ],
)
def test_bad_calls_are_typed_errors(
    arm: KinematicArm, name: str, arguments: dict, message: str
) -> None:
    state = world(GOAL.targets[0].pose)
    with pytest.raises(ToolError, match=message.replace("(", r"\(").replace(")", r"\)")):
        call_tool(name, arguments, context(arm, state))


def test_collision_check_of_a_descent_onto_a_brick(arm: KinematicArm) -> None:
    brick = Pose(position_m=(0.5, 0.0, H / 2), quat_xyzw=yaw_quat(0.0))
    state = world(brick, Pose(position_m=(0.5, 0.3, H / 2), quat_xyzw=yaw_quat(0.0)))
    above = Pose(position_m=(0.5, 0.0, 0.2), quat_xyzw=top_down_quat(0.0))
    grasp = Pose(position_m=(0.5, 0.0, H / 2), quat_xyzw=top_down_quat(0.0))
    # Open, straight down onto brick 0 (ignored as the one being grasped): the fingertips
    # end 1 cm above the ground.
    path = run(
        arm,
        state,
        "collision_check",
        pose=grasp.model_dump(),
        start_pose=above.model_dump(),
        ignore_brick_id=0,
    )
    assert path.reachable and path.collision_free
    assert path.poses_checked == 18
    assert path.clearance_m == pytest.approx(0.01, abs=1e-4)
    assert "ground" in path.closest
    # The same descent with brick 0 counted as an obstacle: closed fingers go through it.
    blocked = run(
        arm,
        state,
        "collision_check",
        pose=grasp.model_dump(),
        start_pose=above.model_dump(),
        gripper_opening_m=0.06,
    )
    assert not blocked.collision_free
    assert blocked.clearance_m == pytest.approx(-(W / 2 - 0.03), abs=1e-3)
    assert "brick 0" in blocked.closest


def test_collision_check_reports_unreachable_poses(arm: KinematicArm) -> None:
    far = Pose(position_m=(1.2, 0.0, 0.2), quat_xyzw=top_down_quat(0.0))
    report = run(arm, world(), "collision_check", pose=far.model_dump())
    assert not report.reachable and not report.collision_free
    assert "no IK solution" in report.closest


def test_contact_and_slip_of_a_brick_held_in_the_real_gripper(
    arm: KinematicArm, scene: Scene
) -> None:
    controller = WaypointController(scene, arm)
    sensor = Sensor(scene, NOISE["none"], trial_seed=0)
    pick_yaw, _ = ClassicalController(controller, sensor).grasp_yaws(
        *sensor.brick_pose(0), GOAL.targets[0].pose
    )
    pick_up(controller, 0, pick_yaw, lift_to_m=0.3)
    state = sensor.perceive(GOAL)
    assert state.brick(0).status == "grasped"
    forces = run(arm, state, "finger_contacts", brick_id=0)
    assert forces.held
    assert forces.normal_n == pytest.approx((110.0, 110.0), rel=0.15)
    assert forces.friction_coefficient == pytest.approx(1.2 * 0.8)
    assert forces.friction_margin_n > 100.0
    assert forces.required_normal_n == pytest.approx(1.5 * 9.81 / (2 * 1.2 * 0.8))
    slip = run(arm, state, "slip_estimate", brick_id=0)
    assert slip.relative_speed_mps < 1e-3
    assert max(abs(v) for v in slip.offset_in_gripper_m) < 2e-3  # centred between the pads
    idle = run(arm, state, "finger_contacts", brick_id=1)
    assert not idle.held and idle.normal_n == (0.0, 0.0)


def test_slip_is_velocity_relative_to_the_moving_gripper(arm: KinematicArm) -> None:
    state = world(Pose(position_m=(0.5, 0.1, 0.3), quat_xyzw=top_down_quat(0.0)))
    robot = state.robot.model_copy(
        update={
            "ee_pose": Pose(position_m=(0.5, 0.0, 0.3), quat_xyzw=top_down_quat(0.0)),
            "ee_angular_velocity_radps": (0.0, 0.0, 1.0),
            "ee_linear_velocity_mps": (0.05, 0.0, 0.0),
        }
    )
    carried = state.bricks[0].model_copy(
        update={"linear_velocity_mps": (-0.05, 0.0, 0.0), "angular_velocity_radps": (0.0, 0.0, 1.0)}
    )
    moving = state.model_copy(update={"robot": robot, "bricks": (carried,)})
    # omega x lever = (0, 0, 1) x (0, 0.1, 0) = (-0.1, 0, 0); plus the tool's (0.05, 0, 0).
    assert run(arm, moving, "slip_estimate", brick_id=0).relative_speed_mps == pytest.approx(0.0)
    sliding = moving.model_copy(
        update={"bricks": (carried.model_copy(update={"linear_velocity_mps": (-0.03, 0.0, 0.0)}),)}
    )
    assert run(arm, sliding, "slip_estimate", brick_id=0).relative_speed_mps == pytest.approx(0.02)
