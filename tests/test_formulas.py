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
