"""The knowledge base's formulas: the slot pose sets the held brick on its target, the
wrist estimate agrees with the arm's inverse kinematics, and each worked example in a
prompt is what the formula computes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actionreasoning.agents import knowledge
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.tools import formulas
from actionreasoning.world.geometry import top_down_quat, yaw_quat
from actionreasoning.world.models import Pose


def test_the_slot_pose_sets_a_rolled_brick_level_on_its_target() -> None:
    tool = Pose(position_m=(0.4, -0.2, 0.3), quat_xyzw=top_down_quat(0.7))
    turn = Rotation.from_euler("x", 180 + 37, degrees=True)  # rolled 37 deg in the hand
    held = formulas.carried(tool, (0.003, -0.002, 0.01), tuple(turn.as_quat()))  # type: ignore[arg-type]
    target = Pose(position_m=(0.6, 0.1, 0.09), quat_xyzw=yaw_quat(1.2))
    slot = formulas.slot_pose(target, *formulas.in_hand(tool, held))
    placed = formulas.carried(slot, *formulas.in_hand(tool, held))
    assert placed.position_m == pytest.approx(target.position_m, abs=1e-12)
    between = Rotation.from_quat(placed.quat_xyzw).inv() * Rotation.from_quat(target.quat_xyzw)
    assert between.magnitude() == pytest.approx(0.0, abs=1e-9)
    tilt = math.degrees(math.acos(-Rotation.from_quat(slot.quat_xyzw).apply([0, 0, 1])[2]))
    assert tilt == pytest.approx(37.0, abs=1e-6)  # the tool tilts by the roll


def test_the_wrist_estimate_is_within_5_deg_of_the_inverse_kinematics() -> None:
    arm, rng, checked = KinematicArm(), np.random.default_rng(7), 0
    for _ in range(120):
        r, heading = rng.uniform(0.35, 0.8), rng.uniform(-0.9 * math.pi, 0.9 * math.pi)
        position = (r * math.cos(heading), r * math.sin(heading), rng.uniform(0.03, 0.45))
        yaw = rng.uniform(-180.0, 180.0)
        solution = arm.solve(position, top_down_quat(math.radians(yaw)))
        if not solution.reached:
            continue
        error = formulas.wrist_deg(position, yaw) - math.degrees(solution.joints_rad[6])
        assert abs((error + 180.0) % 360.0 - 180.0) <= 5.0, (position, yaw)
        checked += 1
    assert checked >= 90


def test_each_worked_example_is_what_its_formula_computes() -> None:
    slot = knowledge.formula_text("slot_pose")
    computed = formulas.slot_pose(
        knowledge.TARGET, *formulas.in_hand(knowledge.TOOL, knowledge.held_example())
    )
    shown = [round(v, 5) for v in computed.position_m]
    assert f"p_s = {shown}".replace("]", "") in slot.replace("\n", " ").replace("]", "")
    grasp = knowledge.formula_text("grasp_yaws")
    best = min(
        formulas.grasp_yaws_deg(knowledge.BRICK.quat_xyzw),
        key=lambda a: formulas.wrist_turn_deg(knowledge.BRICK, knowledge.TARGET, a),
    )
    assert f"Take a = {round(best, 2):g}:" in grasp
    for name in knowledge.FORMULAS:
        assert "Example:" in knowledge.formula_text(name), name
    # The roll rate's example: 0.75 deg over 0.25 s, a 1 s set-down touching down 2 s later.
    assert "ω = 3 deg/s; duration_s 1: Δ = 6 deg" in knowledge.formula_text("roll_rate")


LEVEL_IN_HAND = Rotation.from_euler("x", 180.0, degrees=True)  # held level: a half turn


@pytest.mark.parametrize("roll_deg", [0.0, 10.0, -25.0, 61.0])
def test_the_roll_in_the_hand_is_the_turn_about_the_pads_axis_either_way_up(
    roll_deg: float,
) -> None:
    rolled = Rotation.from_euler("y", roll_deg, degrees=True)
    assert formulas.roll_in_hand_deg(tuple((rolled * LEVEL_IN_HAND).as_quat())) == pytest.approx(
        roll_deg
    )
    assert formulas.roll_in_hand_deg(tuple(rolled.as_quat())) == pytest.approx(roll_deg)


def test_the_roll_rate_slot_against_a_hand_computation() -> None:
    """Held 1 cm below the tool centre point, rolled 10 deg; watched at 100.00 s and 100.25 s
    at 9.25 and 10 deg: 3 deg/s. A set-down of duration 1 s touches down 2 s later, rolled
    6 deg further, 16 deg: o' = R_y(6)(0, 0, 0.01) = (0.0010453, 0, 0.0099452). On a level
    target at (0.6, 0.1, 0.03), q_s = q_h'* = R_x(180) R_y(-16), and
    p_s = p* - R(q_s) o' = p* - R_x(180) R_y(-10)(0, 0, 0.01)
        = p* - R_x(180)(-0.0017365, 0, 0.0098481) = (0.6017365, 0.1, 0.0398481):
    the tool tilted 16 deg, 1.7 mm on along x."""
    offset = (0.0, 0.0, 0.01)
    quat = tuple((Rotation.from_euler("y", 10.0, degrees=True) * LEVEL_IN_HAND).as_quat())
    rate = formulas.roll_rate_deg_s(9.25, 100.0, 10.0, 100.25)
    assert rate == pytest.approx(3.0)
    turn = rate * formulas.touch_down_s(1.0)
    assert turn == pytest.approx(6.0)
    rolled_offset, rolled_quat = formulas.rolled_in_hand(offset, quat, turn)
    assert rolled_offset == pytest.approx((0.0010453, 0.0, 0.0099452), abs=1e-7)
    assert formulas.roll_in_hand_deg(rolled_quat) == pytest.approx(16.0)
    target = Pose(position_m=(0.6, 0.1, 0.03))
    slot = formulas.slot_pose(target, rolled_offset, rolled_quat)
    assert slot.position_m == pytest.approx((0.6017365, 0.1, 0.0398481), abs=1e-7)
    expected = LEVEL_IN_HAND * Rotation.from_euler("y", -16.0, degrees=True)
    assert (Rotation.from_quat(slot.quat_xyzw).inv() * expected).magnitude() < 1e-9
    # The brick as it will sit at touch-down lands exactly on the target, level.
    landing = formulas.carried(slot, rolled_offset, rolled_quat)
    assert landing.position_m == pytest.approx(target.position_m, abs=1e-12)
    assert Rotation.from_quat(landing.quat_xyzw).magnitude() < 1e-9


def test_a_roll_rate_is_taken_within_a_half_turn_and_a_swing_is_not_extrapolated() -> None:
    # A brick rolled past 90 deg reads -89: the change is 2 deg, not -178 deg.
    assert formulas.roll_rate_deg_s(89.0, 10.0, -89.0, 10.25) == pytest.approx(8.0)
    assert formulas.touch_down_turn_deg(8.0, 1.0) == 0.0  # faster than any creep: a swing
    assert formulas.touch_down_turn_deg(-3.0, 1.0) == pytest.approx(-6.0)
    assert formulas.touch_down_turn_deg(5.0, 30.0) == 90.0  # no further than onto its side
