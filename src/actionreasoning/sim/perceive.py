"""perceive(): the one function that turns the simulator into a WorldState."""

from __future__ import annotations

import math

from actionreasoning.sim.robot_model import FINGER_MAX_M, FINGER_MIN_M, FINGER_PAD_BELOW_TCP_M
from actionreasoning.sim.scene import Scene
from actionreasoning.world.geometry import tilt_deg
from actionreasoning.world.models import (
    BrickState,
    BrickStatus,
    GoalPattern,
    Pose,
    Progress,
    RobotState,
    WorldState,
)

GRASP_CONTACT_N = 1.0
TOPPLED_TILT_DEG = 20.0


def perceive(scene: Scene, goal: GoalPattern, progress: Progress = Progress()) -> WorldState:
    """Measure the scene: robot, every brick with its status, the goal and the progress."""
    joints, _ = scene.arm_joints()
    left, right = scene.finger_positions()
    tcp_position, tcp_quat = scene.tcp_pose()
    contacts = [scene.finger_contacts(i) for i in range(len(scene.bricks))]
    held = [c[0].normal_n > GRASP_CONTACT_N and c[1].normal_n > GRASP_CONTACT_N for c in contacts]
    normal, tangential = (0.0, 0.0), (0.0, 0.0)
    if any(held):
        left_c, right_c = contacts[held.index(True)]
        normal = (left_c.normal_n, right_c.normal_n)
        tangential = (left_c.tangential_n, right_c.tangential_n)
    linear, angular = scene.tcp_velocity()
    robot = RobotState(
        ee_pose=Pose(position_m=tcp_position, quat_xyzw=tcp_quat),
        joint_positions_rad=tuple(float(q) for q in joints),
        # The pads' joint limits bound the gap; the solver can overshoot them by microns.
        gripper_width_m=min(max(left + right, 2 * FINGER_MIN_M), 2 * FINGER_MAX_M),
        finger_depth_m=FINGER_PAD_BELOW_TCP_M,
        finger_forces_n=normal,
        finger_tangential_n=tangential,
        finger_friction=scene.physics.finger_friction,
        ee_linear_velocity_mps=linear,
        ee_angular_velocity_radps=angular,
    )
    bricks = []
    for i in range(len(scene.bricks)):
        position, quat = scene.brick_pose(i)
        linear, angular = scene.brick_velocity(i)
        status = _status(scene, i, position, quat, held[i], progress)
        bricks.append(
            BrickState(
                id=i,
                size_m=scene.spec.brick_size_m,
                mass_kg=scene.spec.brick_mass_kg,
                friction=scene.spec.brick_friction,
                pose=Pose(position_m=position, quat_xyzw=quat),
                linear_velocity_mps=linear,
                angular_velocity_radps=angular,
                status=status,
            )
        )
    return WorldState(
        time_s=scene.time_s, robot=robot, bricks=tuple(bricks), goal=goal, progress=progress
    )


def _status(
    scene: Scene, brick: int, position, quat, held: bool, progress: Progress
) -> BrickStatus:
    if held:
        return "grasped"
    if tilt_deg(quat) > TOPPLED_TILT_DEG:
        return "toppled"
    if brick in progress.placed_ids:
        return "placed"
    spec = scene.spec
    radius = math.hypot(position[0], position[1])
    azimuth = math.degrees(math.atan2(position[1], position[0]))
    in_pick_area = (
        spec.pick_radius_m[0] - 0.05 <= radius <= spec.pick_radius_m[1] + 0.05
        and spec.pick_azimuth_deg[0] - 5.0 <= azimuth <= spec.pick_azimuth_deg[1] + 5.0
        and position[2] < spec.brick_size_m[2]
    )
    return "in_pick_area" if in_pick_area else "dropped"
