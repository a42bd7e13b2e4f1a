"""What the robot measures: the simulator seen through its sensors, as a WorldState.

A :class:`Sensor` adds the trial's perception noise to every brick position and yaw and
to the pad forces it reports, each observation a new draw from the trial's own generator
(no draw at all where the noise is zero). The forces of a brick that touches a pad but is
not the held one draw from a second generator of the trial's seed, so that measuring them
leaves the draws of everything else as they were. The agents and the classical script read
the world only through it; metrics and pictures read the true poses from the scene.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from actionreasoning.sim.robot_model import FINGER_MAX_M, FINGER_MIN_M, FINGER_PAD_BELOW_TCP_M
from actionreasoning.sim.scene import GRASP_CONTACT_N, FingerContact, Scene
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import QuatXYZW, Vec3, as_quat, as_vec3, tilt_deg
from actionreasoning.world.models import (
    BrickState,
    BrickStatus,
    GoalPattern,
    PadContact,
    Pose,
    Progress,
    RobotState,
    WorldState,
)
from actionreasoning.world.noise import PERCEPTION_STREAM, NoiseLevel
from actionreasoning.world.supply import PALLET_LAYERS
from actionreasoning.world.support import carriers

TOPPLED_TILT_DEG = 20.0
#: The perception sub-stream of the pad forces of bricks other than the held one (not 0:
#: the seed [seed, stream, 0] draws the same numbers as [seed, stream]).
CONTACT_SUBSTREAM = 1


class Sensor:
    """The scene's measurements with the trial's perception noise."""

    def __init__(self, scene: Scene, noise: NoiseLevel, trial_seed: int) -> None:
        self.scene = scene
        self.noise = noise
        self._rng = np.random.default_rng([trial_seed, PERCEPTION_STREAM])
        self._contact_rng = np.random.default_rng(
            [trial_seed, PERCEPTION_STREAM, CONTACT_SUBSTREAM]
        )
        self.sensing = noise.sensing()

    def brick_pose(self, brick: int) -> tuple[Vec3, QuatXYZW]:
        """Measured position and orientation of a brick (noise on position and yaw)."""
        position, quat = self.scene.brick_pose(brick)
        noise = self.noise.perception
        if noise.position_std_m > 0.0:
            shift = self._rng.normal(0.0, noise.position_std_m, size=3)
            position = as_vec3(np.add(position, shift))
        if noise.yaw_std_deg > 0.0:
            turn = Rotation.from_euler("z", self._rng.normal(0.0, noise.yaw_std_deg), degrees=True)
            quat = as_quat((turn * Rotation.from_quat(quat)).as_quat())
        return position, quat

    def _forces(self, values: tuple[float, float], rng: np.random.Generator) -> tuple[float, float]:
        rel = self.noise.perception.force_rel_std
        if rel == 0.0:
            return values
        factors = 1.0 + rng.normal(0.0, rel, size=2)
        return (max(0.0, values[0] * factors[0]), max(0.0, values[1] * factors[1]))

    def _pad_contacts(
        self,
        contacts: list[tuple[FingerContact, FingerContact]],
        held: int | None,
        held_forces: tuple[tuple[float, float], tuple[float, float]],
    ) -> tuple[PadContact, ...]:
        """Every brick that presses on a pad with its measured forces: brick ``held`` with
        ``held_forces`` (its measurement for finger_forces_n), the others with their own."""
        measured = []
        for brick, (left, right) in enumerate(contacts):
            if left.normal_n <= 0.0 and right.normal_n <= 0.0:
                continue
            if brick == held:
                normal, tangential = held_forces
            else:
                rng = self._contact_rng
                normal = self._forces((left.normal_n, right.normal_n), rng)
                tangential = self._forces((left.tangential_n, right.tangential_n), rng)
            measured.append(PadContact(brick_id=brick, normal_n=normal, tangential_n=tangential))
        return tuple(measured)

    def perceive(self, goal: GoalPattern, progress: Progress = Progress()) -> WorldState:
        """Measure the scene: robot, every brick with its status, the goal and the progress."""
        scene = self.scene
        joints, _ = scene.arm_joints()
        left, right = scene.finger_positions()
        tcp_position, tcp_quat = scene.tcp_pose()
        contacts = [scene.finger_contacts(i) for i in range(len(scene.bricks))]
        held = [all(c.normal_n > GRASP_CONTACT_N for c in pads) for pads in contacts]
        normal, tangential = (0.0, 0.0), (0.0, 0.0)
        first_held = held.index(True) if any(held) else None
        if first_held is not None:
            left_c, right_c = contacts[first_held]
            normal = self._forces((left_c.normal_n, right_c.normal_n), self._rng)
            tangential = self._forces((left_c.tangential_n, right_c.tangential_n), self._rng)
        pad_contacts = self._pad_contacts(contacts, first_held, (normal, tangential))
        linear, angular = scene.tcp_velocity()
        physics = scene.physics
        robot = RobotState(
            ee_pose=Pose(position_m=tcp_position, quat_xyzw=tcp_quat),
            joint_positions_rad=tuple(float(q) for q in joints),
            # The pads' joint limits bound the gap; the solver can overshoot them by microns.
            gripper_width_m=min(max(left + right, 2 * FINGER_MIN_M), 2 * FINGER_MAX_M),
            finger_depth_m=FINGER_PAD_BELOW_TCP_M,
            finger_forces_n=normal,
            finger_tangential_n=tangential,
            pad_contacts=pad_contacts,
            finger_friction=physics.pad_friction,
            grip_force_limit_n=physics.grip_force_n,
            ee_linear_velocity_mps=linear,
            ee_angular_velocity_radps=angular,
        )
        bricks = []
        covered = _covered(scene)
        for i in range(len(scene.bricks)):
            position, quat = self.brick_pose(i)
            linear, angular = scene.brick_velocity(i)
            bricks.append(
                BrickState(
                    id=i,
                    size_m=scene.bodies[i].size_m,
                    mass_kg=scene.nominals[i].mass_kg,
                    friction=scene.nominals[i].lateral_friction,
                    pose=Pose(position_m=position, quat_xyzw=quat),
                    linear_velocity_mps=linear,
                    angular_velocity_radps=angular,
                    status=_status(scene, i, position, quat, held[i], progress, covered),
                )
            )
        return WorldState(
            time_s=scene.time_s,
            robot=robot,
            bricks=tuple(bricks),
            goal=goal,
            progress=progress,
            sensing=self.sensing,
        )


def _covered(scene: Scene) -> set[int]:
    """The bricks another brick lies on (true poses: whether one brick lies on another is
    plain to see, whatever the noise of its measured position)."""
    boxes = [
        Box(*scene.brick_pose(i), scene.bodies[i].size_m, id=i)
        for i in range(len(scene.bricks))
        if i not in scene.queue
    ]
    return {lower.named_id for upper in boxes for lower, _ in carriers(upper, boxes)}


def _status(
    scene: Scene,
    brick: int,
    position: Vec3,
    quat: QuatXYZW,
    held: bool,
    progress: Progress,
    covered: set[int],
) -> BrickStatus:
    if brick in scene.queue:
        return BrickStatus.QUEUED
    if held:
        return BrickStatus.GRASPED
    if tilt_deg(quat) > TOPPLED_TILT_DEG:
        return BrickStatus.TOPPLED
    if brick in progress.placed_ids:
        return BrickStatus.PLACED
    spec = scene.spec
    radius = math.hypot(position[0], position[1])
    azimuth = math.degrees(math.atan2(position[1], position[0]))
    in_pick_area = (
        spec.pick_radius_m[0] - 0.05 <= radius <= spec.pick_radius_m[1] + 0.05
        and spec.pick_azimuth_deg[0] - 5.0 <= azimuth <= spec.pick_azimuth_deg[1] + 5.0
        and position[2] < scene.bodies[brick].size_m[2] * PALLET_LAYERS
    )
    if not in_pick_area:
        return BrickStatus.DROPPED
    return BrickStatus.COVERED if brick in covered else BrickStatus.IN_PICK_AREA
