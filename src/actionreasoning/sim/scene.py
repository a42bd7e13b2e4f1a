"""The PyBullet world: ground, arm with gripper, and bricks, in DIRECT (headless) mode.

Every setting comes from the trial's :class:`PhysicsProfile` (``world/physics.py``). Under
``paper`` (PyBullet's defaults) a held 1.5 kg brick rolls and creeps in the hand and the
pads deliver about 40 N of the 110 N commanded; under ``precise`` (measured with
``bench/grip_slip.py``) friction anchors with a 1/480 s step and 150 solver iterations stop
both. With anchors on, the pads' contacts are dropped for one step when the gripper
opens, or a released brick stays stuck to a pad. ``deterministicOverlappingPairs`` is on
under every profile: it makes a trial repeatable and changes no contact property.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pybullet as p
import pybullet_data

from actionreasoning.errors import TrialAborted
from actionreasoning.records import FailureCode
from actionreasoning.sim.robot_model import (
    ARM_JOINTS,
    FINGER_LEFT,
    FINGER_MAX_M,
    FINGER_MIN_M,
    FINGER_RIGHT,
    TCP_LINK,
    load_robot,
)
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.geometry import Joints, QuatXYZW, Vec3, as_quat, as_vec3
from actionreasoning.world.models import Pose
from actionreasoning.world.physics import GRAVITY_MPS2, PAPER, PhysicsProfile
from actionreasoning.world.scene_spec import BrickBody, SceneSpec
from actionreasoning.world.supply import feeder_pose

#: A pad pressing on a brick with more than this (N) is in contact with it.
GRASP_CONTACT_N = 1.0

BRICK_COLORS = (
    (0.80, 0.30, 0.22, 1.0),
    (0.85, 0.45, 0.25, 1.0),
    (0.70, 0.25, 0.20, 1.0),
    (0.90, 0.55, 0.35, 1.0),
    (0.75, 0.35, 0.30, 1.0),
    (0.65, 0.30, 0.15, 1.0),
)

#: Wall time is looked at every this many steps (and before every agent call).
WALL_CHECK_TICKS = 240
#: How often the feeder looks whether to feed (time steps), and how far (m, in the plane)
#: the last brick and the tool must be from its pose: a brick's length beyond the pick
#: area's spacing of catalogue bricks.
FEED_TICKS = 60
FEED_CLEAR_M = 0.25
#: A brick farther than this from the base (m, along any axis) was flung away.
WORLD_HALF_SIZE_M = 3.0


@dataclass(frozen=True)
class FingerContact:
    """Contact between one finger pad and one brick, summed over contact points (N)."""

    normal_n: float
    tangential_n: float


class Scene:
    """One trial's world. Bricks have ids 0..n-1 in spawn order.

    ``nominals`` are the bricks the agents are told of, one per pose (default: the spec's
    catalogue brick); ``bodies`` are the bricks spawned (default: the nominal ones). A
    feeder's ``queue`` (brick ids, next first) waits where its poses put it; every FEED_TICKS
    the next goes to the feeder's pose once nothing is within FEED_CLEAR_M of it.
    """

    def __init__(
        self,
        spec: SceneSpec,
        brick_poses: Sequence[Pose],
        ready_joints_rad: Joints,
        physics: PhysicsProfile = PAPER,
        budget: TrialBudget = TrialBudget(),
        bodies: Sequence[BrickBody] | None = None,
        nominals: Sequence[BrickBody] | None = None,
        queue: Sequence[int] = (),
    ) -> None:
        self.spec = spec
        self.physics = physics
        catalogue = spec.brick_body(physics.brick_lateral_friction)
        self.nominals = tuple(nominals) if nominals is not None else (catalogue,) * len(brick_poses)
        self.bodies = tuple(bodies) if bodies is not None else self.nominals
        self.budget = budget
        self._deadline = time.monotonic() + budget.max_wall_s
        self.client = p.connect(p.DIRECT)
        self._setup_physics()
        self.robot = load_robot(self.client)
        self._setup_gripper()
        self.bricks = [self._spawn_brick(i, pose) for i, pose in enumerate(brick_poses)]
        self.queue = list(queue)
        for joint, angle in zip(ARM_JOINTS, ready_joints_rad, strict=False):
            p.resetJointState(self.robot, joint, angle, physicsClientId=self.client)
        self.arm_targets = np.array(ready_joints_rad, dtype=float)
        self.finger_target_m = FINGER_MAX_M
        self.ticks = 0
        self._watchers: list[tuple[int, Callable[[Scene], None]]] = []
        self._apply_targets()

    # --- set-up -----------------------------------------------------------------------
    def _setup_physics(self) -> None:
        cfg, cid = self.physics, self.client
        p.setGravity(0, 0, -GRAVITY_MPS2, physicsClientId=cid)
        p.setPhysicsEngineParameter(
            fixedTimeStep=cfg.time_step_s,
            numSolverIterations=cfg.solver_iterations,
            contactBreakingThreshold=cfg.contact_breaking_threshold_m,
            deterministicOverlappingPairs=1,
            physicsClientId=cid,
        )
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        self.ground = p.loadURDF("plane.urdf", physicsClientId=cid)
        p.changeDynamics(
            self.ground, -1, lateralFriction=cfg.ground_lateral_friction, physicsClientId=cid
        )

    def _setup_gripper(self) -> None:
        cfg, cid = self.physics, self.client
        for finger in (FINGER_LEFT, FINGER_RIGHT):
            p.changeDynamics(
                self.robot,
                finger,
                lateralFriction=cfg.pad_friction,
                spinningFriction=cfg.pad_spinning_friction,
                rollingFriction=0.0,
                physicsClientId=cid,
            )
            p.resetJointState(self.robot, finger, FINGER_MAX_M, physicsClientId=cid)
        gear = p.createConstraint(
            self.robot,
            FINGER_LEFT,
            self.robot,
            FINGER_RIGHT,
            p.JOINT_GEAR,
            [0, 1, 0],
            [0, 0, 0],
            [0, 0, 0],
            physicsClientId=cid,
        )
        # Couple the fingers (ratio -1: they move as mirror images) so that the finger that
        # touches first cannot push the brick off centre.
        p.changeConstraint(gear, gearRatio=-1, erp=0.1, maxForce=200, physicsClientId=cid)

    def _spawn_brick(self, index: int, pose: Pose) -> int:
        cid, body_spec = self.client, self.bodies[index]
        half = [s / 2.0 for s in body_spec.size_m]
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=cid)
        visual = p.createVisualShape(
            p.GEOM_BOX,
            halfExtents=half,
            rgbaColor=BRICK_COLORS[index % len(BRICK_COLORS)],
            physicsClientId=cid,
        )
        body = p.createMultiBody(
            baseMass=body_spec.mass_kg,
            baseCollisionShapeIndex=shape,
            baseVisualShapeIndex=visual,
            basePosition=pose.position_m,
            baseOrientation=pose.quat_xyzw,
            physicsClientId=cid,
        )
        p.changeDynamics(
            body,
            -1,
            lateralFriction=body_spec.lateral_friction,
            spinningFriction=self.physics.brick_spinning_friction,
            rollingFriction=self.physics.brick_rolling_friction,
            frictionAnchor=int(self.physics.friction_anchors),
            physicsClientId=cid,
        )
        return body

    # --- actuation --------------------------------------------------------------------
    def set_arm_targets(self, joints_rad: Joints) -> None:
        """Position targets for the seven arm joints (applied from the next step on)."""
        self.arm_targets = np.asarray(joints_rad, dtype=float)
        self._apply_targets()

    def set_finger_target(self, half_width_m: float) -> None:
        """Drive each finger pad to ``half_width_m`` from the centre, with the grip force limit.

        Opening drops the pads' contacts for one time step first: an anchored contact point
        would otherwise keep the released brick stuck to a pad.
        """
        target = float(np.clip(half_width_m, FINGER_MIN_M, FINGER_MAX_M))
        if self.physics.friction_anchors and target > self.finger_target_m:
            self._drop_pad_contacts()
        self.finger_target_m = target
        self._apply_targets()

    def _drop_pad_contacts(self) -> None:
        cid = self.client
        pairs = [(brick, finger) for brick in self.bricks for finger in (FINGER_LEFT, FINGER_RIGHT)]
        for brick, finger in pairs:
            p.setCollisionFilterPair(self.robot, brick, finger, -1, 0, physicsClientId=cid)
        self.step()
        for brick, finger in pairs:
            p.setCollisionFilterPair(self.robot, brick, finger, -1, 1, physicsClientId=cid)

    def _apply_targets(self) -> None:
        cfg, cid = self.physics, self.client
        p.setJointMotorControlArray(
            self.robot,
            list(ARM_JOINTS),
            p.POSITION_CONTROL,
            targetPositions=list(self.arm_targets),
            forces=[cfg.arm_force_nm] * len(ARM_JOINTS),
            physicsClientId=cid,
        )
        for finger in (FINGER_LEFT, FINGER_RIGHT):
            p.setJointMotorControl2(
                self.robot,
                finger,
                p.POSITION_CONTROL,
                targetPosition=self.finger_target_m,
                force=cfg.grip_force_n,
                maxVelocity=cfg.finger_speed_mps,
                physicsClientId=cid,
            )

    def watch(self, every_ticks: int, observer: Callable[[Scene], None]) -> None:
        """Call ``observer(self)`` after every ``every_ticks``-th time step; it must only read."""
        self._watchers.append((max(1, every_ticks), observer))

    def ticks_for(self, seconds: float) -> int:
        """The number of time steps (at least one) that lasts ``seconds``."""
        return max(1, round(seconds / self.physics.time_step_s))

    def step(self, ticks: int = 1) -> None:
        """Advance the simulation by ``ticks`` fixed time steps, within the trial's budget."""
        for _ in range(ticks):
            p.stepSimulation(physicsClientId=self.client)
            self.ticks += 1
            if self.ticks > self.budget.max_steps:
                raise TrialAborted(
                    FailureCode.STEP_BUDGET, f"{self.budget.max_steps} simulation steps spent"
                )
            if self.ticks % WALL_CHECK_TICKS == 0:
                self.check_wall_time()
            if self.queue and self.ticks % FEED_TICKS == 0:
                self._feed()
            for every, observer in self._watchers:
                if self.ticks % every == 0:
                    observer(self)

    def _feed(self) -> None:
        """Put the feeder's next brick at the feeder's pose if nothing is near it."""
        feed = feeder_pose()
        near = [self.tcp_pose()[0]] + [
            self.brick_pose(i)[0] for i in range(len(self.bricks)) if i not in self.queue
        ]
        if any(math.dist(feed.position_m[:2], at[:2]) < FEED_CLEAR_M for at in near):
            return
        brick = self.queue.pop(0)
        x, y, _ = feed.position_m
        position = (x, y, self.bodies[brick].size_m[2] / 2.0)
        cid = self.client
        p.resetBasePositionAndOrientation(
            self.bricks[brick], position, feed.quat_xyzw, physicsClientId=cid
        )
        p.resetBaseVelocity(self.bricks[brick], (0, 0, 0), (0, 0, 0), physicsClientId=cid)

    @property
    def deadline(self) -> float:
        """When the trial's wall time runs out, in ``time.monotonic()`` seconds."""
        return self._deadline

    def check_wall_time(self) -> None:
        """Raise ``TrialAborted("time_budget", ...)`` once the trial's wall time is spent."""
        if time.monotonic() > self._deadline:
            raise TrialAborted(
                FailureCode.TIME_BUDGET, f"{self.budget.max_wall_s:g} s of wall time spent"
            )

    def check_physics(self) -> None:
        """Raise ``TrialAborted("physics_blowup", ...)`` if the state is not finite or a
        brick was flung out of the world."""
        joints, speeds = self.arm_joints()
        if not (np.all(np.isfinite(joints)) and np.all(np.isfinite(speeds))):
            raise TrialAborted(FailureCode.PHYSICS_BLOWUP, "the arm's joint state is not finite")
        for brick in range(len(self.bricks)):
            position, quat = self.brick_pose(brick)
            inside = all(abs(v) <= WORLD_HALF_SIZE_M for v in position) and position[2] > -0.5
            if not (np.all(np.isfinite([*position, *quat])) and inside):
                where = ", ".join(f"{v:.3f}" for v in position)
                raise TrialAborted(
                    FailureCode.PHYSICS_BLOWUP, f"brick {brick} was flung to ({where}) m"
                )

    # --- measurement ------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Simulated time since the scene was built."""
        return self.ticks * self.physics.time_step_s

    def arm_joints(self) -> tuple[np.ndarray, np.ndarray]:
        """Measured arm joint angles (rad) and velocities (rad/s)."""
        states = p.getJointStates(self.robot, list(ARM_JOINTS), physicsClientId=self.client)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])

    def finger_positions(self) -> tuple[float, float]:
        """Measured distance of each finger pad from the gripper centre (m)."""
        left, right = p.getJointStates(
            self.robot, [FINGER_LEFT, FINGER_RIGHT], physicsClientId=self.client
        )
        return left[0], right[0]

    def tcp_pose(self) -> tuple[Vec3, QuatXYZW]:
        """Measured tool-centre-point pose."""
        state = p.getLinkState(
            self.robot, TCP_LINK, computeForwardKinematics=True, physicsClientId=self.client
        )
        return as_vec3(state[4]), as_quat(state[5])

    def link_positions(self) -> list[Vec3]:
        """World positions of the arm's base and every link frame, from base to tool."""
        cid, links = self.client, range(p.getNumJoints(self.robot, physicsClientId=self.client))
        base = p.getBasePositionAndOrientation(self.robot, physicsClientId=cid)[0]
        states = p.getLinkStates(self.robot, list(links), physicsClientId=cid)
        return [as_vec3(base), *(as_vec3(state[4]) for state in states)]

    def tcp_velocity(self) -> tuple[Vec3, Vec3]:
        """Measured tool-centre-point linear (m/s) and angular (rad/s) velocity."""
        state = p.getLinkState(
            self.robot, TCP_LINK, computeLinkVelocity=True, physicsClientId=self.client
        )
        return as_vec3(state[6]), as_vec3(state[7])

    def brick_pose(self, brick: int) -> tuple[Vec3, QuatXYZW]:
        """Measured pose of brick ``brick``."""
        position, quat = p.getBasePositionAndOrientation(
            self.bricks[brick], physicsClientId=self.client
        )
        return as_vec3(position), as_quat(quat)

    def brick_velocity(self, brick: int) -> tuple[Vec3, Vec3]:
        """Measured linear (m/s) and angular (rad/s) velocity of brick ``brick``."""
        linear, angular = p.getBaseVelocity(self.bricks[brick], physicsClientId=self.client)
        return as_vec3(linear), as_vec3(angular)

    def finger_contacts(self, brick: int) -> tuple[FingerContact, FingerContact]:
        """Normal and tangential contact force between each finger pad and a brick."""
        return (
            self._contact(self.bricks[brick], FINGER_LEFT),
            self._contact(self.bricks[brick], FINGER_RIGHT),
        )

    def is_held(self, brick: int) -> bool:
        """Whether both finger pads press on a brick (more than GRASP_CONTACT_N each)."""
        return all(c.normal_n > GRASP_CONTACT_N for c in self.finger_contacts(brick))

    def support_force(self, brick: int) -> float:
        """Total normal force (N) on a brick from everything but the robot: what carries it."""
        body = self.bricks[brick]
        points = p.getContactPoints(bodyA=body, physicsClientId=self.client)
        return float(sum(pt[9] for pt in points if pt[2] != self.robot))

    def _contact(self, body: int, finger: int) -> FingerContact:
        points = p.getContactPoints(
            bodyA=self.robot, bodyB=body, linkIndexA=finger, physicsClientId=self.client
        )
        normal = sum(pt[9] for pt in points)
        friction = sum(
            (pt[10] * np.asarray(pt[11]) + pt[12] * np.asarray(pt[13]) for pt in points),
            np.zeros(3),
        )
        return FingerContact(normal_n=float(normal), tangential_n=float(np.linalg.norm(friction)))

    def close(self) -> None:
        """Disconnect from the physics server."""
        if p.isConnected(self.client):
            p.disconnect(self.client)
