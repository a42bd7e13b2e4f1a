"""The knowledge base's formulas: what an agent computes itself in the ``check`` and
``none`` tiers, where no tool returns a pose to answer with.

Each is a pure function of poses a prompt shows. The prompts state them in words and
symbols with worked examples rendered by these same functions
(``agents/prompts/formulas/``), the built-in reasoner computes with them, and the
``solve`` tier's tools (``grasp_options``, ``placement_pose``) call them, so a formula, its
worked example and the tool that solves it cannot disagree.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.world.geometry import QuatXYZW, Vec3, quat_yaw, wrap_angle
from actionreasoning.world.models import Pose

#: The approach pose is this far straight above the grasp pose (m).
APPROACH_HEIGHT_M = 0.12
#: The wrist joint of the arm turns at most this far either way (deg; the iiwa's A7).
WRIST_LIMIT_DEG = 175.0


def _vec(values: np.ndarray) -> Vec3:
    return (float(values[0]), float(values[1]), float(values[2]))


def _quat(rotation: Rotation) -> QuatXYZW:
    x, y, z, w = rotation.as_quat()
    return (float(x), float(y), float(z), float(w))


def grasp_yaws_deg(brick_quat: QuatXYZW) -> tuple[float, float]:
    """The two tool yaws (deg, in [-180, 180)) whose pads close across a brick's width: the
    brick's yaw and the yaw half a turn from it."""
    yaw = quat_yaw(brick_quat)
    return (
        math.degrees(wrap_angle(yaw)),
        math.degrees(wrap_angle(yaw + math.pi)),
    )


def grasp_pose(brick: Pose, size_m: Vec3, quat_xyzw: QuatXYZW) -> Pose:
    """The tool at orientation ``quat_xyzw`` (pointing down at a grasp yaw) at a brick's
    centre: x, y its centre's, z half its height above the ground or the layer of a stack it
    lies on (a brick is picked from the ground or a pallet, whatever a noisy measurement of
    its height says: the whole number of brick heights nearest its measured bottom)."""
    x, y, z = brick.position_m
    height = size_m[2]
    layers = max(0, round((z - height / 2.0) / height))
    return Pose(position_m=(x, y, (layers + 0.5) * height), quat_xyzw=quat_xyzw)


def approach_pose(grasp: Pose) -> Pose:
    """The pose APPROACH_HEIGHT_M straight above ``grasp``."""
    x, y, z = grasp.position_m
    return Pose(position_m=(x, y, z + APPROACH_HEIGHT_M), quat_xyzw=grasp.quat_xyzw)


def wrist_deg(position_m: Vec3, yaw_deg: float) -> float:
    """The wrist joint's angle (deg) with the tool pointing down at yaw ``yaw_deg`` at
    ``position_m``: the heading of the position from the base, minus the yaw, plus a half
    turn, wrapped to [-180, 180). Within 5 deg of the arm's inverse kinematics over the
    workspace (``bench/wrist_estimate.py``; ``tests/test_formulas.py`` checks the bound)."""
    heading = math.atan2(position_m[1], position_m[0])
    return math.degrees(wrap_angle(heading - math.radians(yaw_deg) + math.pi))


def place_yaw_deg(grasp_yaw_deg: float, brick_quat: QuatXYZW, target_quat: QuatXYZW) -> float:
    """The tool's yaw (deg) over the target for a brick grasped at ``grasp_yaw_deg``: the
    grasp yaw turned by the target's yaw minus the brick's."""
    turn = quat_yaw(target_quat) - quat_yaw(brick_quat)
    return math.degrees(wrap_angle(math.radians(grasp_yaw_deg) + turn))


def wrist_turn_deg(brick: Pose, target: Pose, grasp_yaw_deg: float) -> float:
    """The larger wrist turn (deg, absolute) of a grasp at ``grasp_yaw_deg``: at the brick
    and, carried there, over the target. The grasp yaw with the smaller one is taken."""
    place = place_yaw_deg(grasp_yaw_deg, brick.quat_xyzw, target.quat_xyzw)
    return max(
        abs(wrist_deg(brick.position_m, grasp_yaw_deg)),
        abs(wrist_deg(target.position_m, place)),
    )


def in_hand(tool: Pose, brick: Pose) -> tuple[Vec3, QuatXYZW]:
    """A brick's pose in the tool frame: its centre's offset o = R(q_tool)^T (p_brick -
    p_tool) and its orientation q_h = q_tool* (x) q_brick."""
    grip = Rotation.from_quat(tool.quat_xyzw)
    offset = grip.inv().apply(np.subtract(brick.position_m, tool.position_m))
    return _vec(offset), _quat(grip.inv() * Rotation.from_quat(brick.quat_xyzw))


def slot_pose(target: Pose, offset_m: Vec3, quat_in_hand: QuatXYZW) -> Pose:
    """The tool pose that sets a brick held at (``offset_m``, ``quat_in_hand``) exactly on
    ``target``: q_slot = q_target (x) q_h*, p_slot = p_target - R(q_slot) o. A brick rolled
    in the hand makes q_slot tilt the tool, which sets the brick level."""
    turn = Rotation.from_quat(target.quat_xyzw) * Rotation.from_quat(quat_in_hand).inv()
    position = np.asarray(target.position_m) - turn.apply(offset_m)
    return Pose(position_m=_vec(position), quat_xyzw=_quat(turn))


def roll_in_hand_deg(quat_in_hand: QuatXYZW) -> float:
    """The brick's roll in the hand (deg): its turn about the tool's y axis, the axis through
    both pads. With u = R(q_h)·(0, 0, 1), the brick's up axis in the tool frame, taken with
    u_z <= 0 (a brick is the same upside down): roll = atan2(-u_x, -u_z); 0 when level."""
    up = Rotation.from_quat(quat_in_hand).apply((0.0, 0.0, 1.0))
    if up[2] > 0.0:
        up = -up
    return math.degrees(math.atan2(-up[0], -up[2]))


#: The fastest roll in the hand that is a creep (deg/s): twice the fastest creep measured,
#: a half brick's 3.1 deg/s (``bench/hand_creep.py``). A faster one is a swing, which does
#: not go on at its rate: it is not extrapolated.
CREEP_MAX_DEG_S = 6.0


def roll_rate_deg_s(before_deg: float, before_s: float, now_deg: float, now_s: float) -> float:
    """The roll rate in the hand (deg/s) from two consecutive measurements of the roll: the
    change, taken within a half turn either way (a roll is defined to a half turn), over
    the time between them."""
    change = (now_deg - before_deg + 90.0) % 180.0 - 90.0
    return change / (now_s - before_s)


def touch_down_turn_deg(rate_deg_s: float, duration_s: float) -> float:
    """How much further the brick rolls in the hand by touch-down (deg): the rate times the
    touch-down time (:func:`touch_down_s`) for a creep, at most 90 either way (a brick rolls
    no further than onto its side); 0 for a rate above CREEP_MAX_DEG_S (a swing)."""
    if abs(rate_deg_s) > CREEP_MAX_DEG_S:
        return 0.0
    return max(-90.0, min(90.0, rate_deg_s * touch_down_s(duration_s)))


def rolled_in_hand(
    offset_m: Vec3, quat_in_hand: QuatXYZW, turn_deg: float
) -> tuple[Vec3, QuatXYZW]:
    """A held brick's pose in the tool frame once it has rolled ``turn_deg`` further about
    the pads' axis (the tool's y axis through the tool centre point):
    o' = R_y(turn)·o, q_h' = R_y(turn) ⊗ q_h."""
    if turn_deg == 0.0:
        return offset_m, quat_in_hand
    turn = Rotation.from_euler("y", turn_deg, degrees=True)
    return _vec(turn.apply(offset_m)), _quat(turn * Rotation.from_quat(quat_in_hand))


def touch_down_s(duration_s: float) -> float:
    """When a set-down touches down after it is answered (s): it moves over the slot and then
    down onto it, each move taking the answer's duration_s."""
    return 2.0 * duration_s


def carried(tool: Pose, offset_m: Vec3, quat_in_hand: QuatXYZW) -> Pose:
    """Where a brick held at (``offset_m``, ``quat_in_hand``) is with the tool at ``tool``."""
    grip = Rotation.from_quat(tool.quat_xyzw)
    position = np.add(tool.position_m, grip.apply(offset_m))
    return Pose(position_m=_vec(position), quat_xyzw=_quat(grip * Rotation.from_quat(quat_in_hand)))


def move_duration_s(start_m: Vec3, end_m: Vec3, speed_mps: float) -> float:
    """How long a move takes at ``speed_mps``: the straight distance (m) from its start
    position to its end position over the speed (m/s)."""
    return math.dist(start_m, end_m) / speed_mps
