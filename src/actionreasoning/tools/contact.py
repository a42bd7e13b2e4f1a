"""Contact tools over the measured pads: the forces of any brick a finger pad touches, held
or not, and the slip of the held brick.

Forces are what the simulator measured on the finger pads (N); velocities are world-frame.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field
from scipy.spatial.transform import Rotation

from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.tools.geometry import BrickQuery, brick_state
from actionreasoning.world.geometry import axis_angle_deg
from actionreasoning.world.models import BrickStatus
from actionreasoning.world.physics import GRAVITY_MPS2


class ContactForces(ToolModel):
    """Per-pad contact between the gripper and a brick, held or not (zeros on a pad it does
    not touch)."""

    brick_id: int
    held: bool = Field(description="Both pads press on this brick.")
    normal_n: tuple[float, float] = Field(description="Normal force on the left and right pad.")
    tangential_n: tuple[float, float] = Field(description="Friction force on each pad.")
    friction_coefficient: float = Field(description="Pad friction x brick friction.")
    friction_margin_n: float = Field(
        description="mu x (sum of normal forces) - (sum of friction forces): the friction the "
        "grasp has left; < 0 means the brick slides."
    )
    required_normal_n: float = Field(
        description="Normal force per pad whose friction just carries the brick's weight, "
        "m g / (2 mu), from its catalogue mass and friction; a grasp needs a safety factor more."
    )


class SlipEstimate(ToolModel):
    """Motion of a brick relative to the gripper."""

    brick_id: int
    relative_speed_mps: float = Field(
        description="Brick centre velocity minus the gripper's velocity at that point."
    )
    relative_angular_speed_radps: float
    offset_in_gripper_m: tuple[float, float, float] = Field(
        description="Brick centre in the tool frame (x along the pads, y across, z down)."
    )
    tilt_in_hand_deg: float = Field(
        0.0,
        description="How far the brick has rolled in the hand: the angle between its z axis "
        "and the tool's (0 to 90).",
    )


def finger_contacts(context: ToolContext, query: BrickQuery) -> ContactForces:
    """Normal and tangential force on each finger pad from a brick, held or not (a pad
    resting on its top or pressing one side wall shows here), and the friction margin."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    robot = state.robot
    contact = next((c for c in robot.pad_contacts if c.brick_id == brick.id), None)
    normal = contact.normal_n if contact else (0.0, 0.0)
    tangential = contact.tangential_n if contact else (0.0, 0.0)
    mu = robot.finger_friction * brick.friction
    return ContactForces(
        brick_id=brick.id,
        held=brick.status == BrickStatus.GRASPED,
        normal_n=normal,
        tangential_n=tangential,
        friction_coefficient=mu,
        friction_margin_n=mu * sum(normal) - sum(tangential),
        required_normal_n=brick.mass_kg * GRAVITY_MPS2 / (2.0 * mu) if mu > 0 else math.inf,
    )


def slip_estimate(context: ToolContext, query: BrickQuery) -> SlipEstimate:
    """How fast a brick moves relative to the gripper, and where it sits in the tool frame."""
    state = context.state
    brick = brick_state(state, query.brick_id)
    tool = state.robot.ee_pose
    lever = np.subtract(brick.pose.position_m, tool.position_m)
    omega = np.asarray(state.robot.ee_angular_velocity_radps)
    carried = np.asarray(state.robot.ee_linear_velocity_mps) + np.cross(omega, lever)
    relative = np.asarray(brick.linear_velocity_mps) - carried
    spin = np.asarray(brick.angular_velocity_radps) - omega
    offset = Rotation.from_quat(tool.quat_xyzw).inv().apply(lever)
    return SlipEstimate(
        brick_id=brick.id,
        relative_speed_mps=float(np.linalg.norm(relative)),
        relative_angular_speed_radps=float(np.linalg.norm(spin)),
        offset_in_gripper_m=tuple(float(v) for v in offset),
        tilt_in_hand_deg=axis_angle_deg(brick.pose.quat_xyzw, tool.quat_xyzw),
    )


FINGER_CONTACTS = tool("finger_contacts", finger_contacts)
SLIP = tool("slip_estimate", slip_estimate)
