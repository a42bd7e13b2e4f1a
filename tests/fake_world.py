"""A scripted stand-in for the simulator behind the agents' World protocol.

:class:`FakeWorld` keeps one true state and updates it kinematically, with no physics
stepped: a move puts the tool where it was sent (the real kinematic arm solves IK and
refuses what it cannot reach); a closed gripper holds the brick between its pads and
carries it rigidly; a brick carried down onto something turns level and slides up in the
hand, and a guarded move (a set-down) stops where the brick touches; an opened gripper lets
the brick fall flat onto whatever is under it.

A test scripts what goes wrong with :meth:`FakeWorld.script`: a :class:`Deviation` changes
a move or a grip at a named stage (the step of the last observation), e.g. the brick slips
in the hand on the lift. Measurements are exact (no sensing noise).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.spatial.transform import Rotation
from shapely.geometry import Polygon

from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.errors import UnreachableError
from actionreasoning.tools.base import ToolContext
from actionreasoning.tools.ports import ArmModel, ClearanceChecker
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import (
    QuatXYZW,
    Vec3,
    quat_yaw,
    tilt_deg,
    wrap_angle,
    yaw_quat,
)
from actionreasoning.world.models import (
    READY_POSE,
    BrickState,
    BrickStatus,
    GoalPattern,
    PadContact,
    Pose,
    Progress,
    RobotState,
    Sensing,
    WorldState,
)
from actionreasoning.world.motion import Motion
from actionreasoning.world.physics import GRAVITY_MPS2
from actionreasoning.world.scene_spec import FINGERTIPS_BEYOND_TCP_M, GRIPPER_GAP_M, SceneSpec

#: The force each pad presses a held brick with (the real pads press up to 110 N).
GRIP_N = 40.0
#: A brick this much below its support's top touches it (a guarded move stops there).
TOUCH_M = 1e-4
#: A brick's width axis this close to the pads' closing axis fits between them.
GRASP_YAW_DEG = 10.0
#: Beyond this tilt a brick counts as toppled (as the real sensor counts it).
TOPPLED_DEG = 20.0
#: The simulation tick a move's duration is counted in (PyBullet's default step).
TICK_S = 1.0 / 240.0

Event = Literal["move", "close", "open"]


@dataclass
class _Brick:
    pose: Pose
    size_m: Vec3
    velocity_mps: Vec3 = (0.0, 0.0, 0.0)


@dataclass
class Deviation:
    """What goes wrong on one world call of kind ``event`` at the stage it is scripted for.

    ``apply`` does the call instead of the world (it may call the ideal one and change the
    result); ``only`` picks which calls of that kind it rides on (default: the next one).
    """

    event: Event
    apply: Callable[..., Motion | None]
    only: Callable[[FakeWorld, WaypointProposal | None, int | None], bool] | None = None


@dataclass
class _Scripted:
    stage: str
    deviation: Deviation
    times: float


@dataclass
class Move:
    """A move the world made: at which stage, to where, and what it reported."""

    stage: str | None
    waypoint: WaypointProposal
    stop_on_contact: int | None
    motion: Motion


class FakeWorld:
    """The agents' :class:`World`, kinematic and scripted (see the module docstring)."""

    def __init__(
        self,
        goal: GoalPattern,
        bricks: Sequence[Pose],
        arm: ArmModel,
        collisions: ClearanceChecker,
        spec: SceneSpec = SceneSpec(),
        mass_kg: float = 1.5,
        friction: float = 0.5,
    ) -> None:
        self.goal = goal
        self.spec = spec
        self.sensing = Sensing()
        self.arm = arm
        self.collisions = collisions
        self.mass_kg = mass_kg
        self.friction = friction
        self.bricks = [_Brick(pose, goal.brick_size_m) for pose in bricks]
        self.tool = READY_POSE
        self.joints = self._solve(READY_POSE, None)
        self.width = GRIPPER_GAP_M[1]
        self.held: int | None = None
        self._grip = (np.zeros(3), Rotation.identity())  # the held brick in the tool frame
        self.pads: dict[int, tuple[float, float]] = {}
        self.stage: str | None = None
        self.moves: list[Move] = []
        #: State time: each move takes its duration_s (a move without one, a second).
        self.clock_s = 0.0
        self._script: list[_Scripted] = []

    # --- the World protocol -------------------------------------------------------------
    def observe(self, progress: Progress) -> WorldState:
        """The true state now; its step becomes the stage scripted deviations look for."""
        self.stage = progress.step
        held_forces = self.pads[self.held] if self.held is not None else (0.0, 0.0)
        return WorldState(
            time_s=self.clock_s,
            robot=RobotState(
                ee_pose=self.tool,
                joint_positions_rad=self.joints,
                gripper_width_m=self.width,
                finger_depth_m=FINGERTIPS_BEYOND_TCP_M,
                finger_forces_n=held_forces,
                finger_tangential_n=self._tangential(self.held),
                pad_contacts=tuple(
                    PadContact(brick_id=i, normal_n=n, tangential_n=self._tangential(i))
                    for i, n in sorted(self.pads.items())
                ),
            ),
            bricks=tuple(
                BrickState(
                    id=i,
                    size_m=b.size_m,
                    mass_kg=self.mass_kg,
                    friction=self.friction,
                    pose=b.pose,
                    linear_velocity_mps=b.velocity_mps,
                    status=self._status(i, progress),
                )
                for i, b in enumerate(self.bricks)
            ),
            goal=self.goal,
            progress=progress,
            sensing=self.sensing,
        )

    def tools(self, state: WorldState) -> ToolContext:
        return ToolContext(state=state, arm=self.arm, collisions=self.collisions)

    def move(self, waypoint: WaypointProposal, stop_on_contact: int | None = None) -> Motion:
        deviation = self._scripted("move", waypoint, stop_on_contact)
        if deviation is None:
            done = self.ideal_move(waypoint, stop_on_contact)
        else:
            done = deviation.apply(self, waypoint, stop_on_contact)
        self.moves.append(Move(self.stage, waypoint, stop_on_contact, done))
        self.clock_s += waypoint.duration_s or 1.0
        return done

    def grip(self, opening_m: float | None) -> None:
        event: Event = "close" if opening_m is None else "open"
        deviation = self._scripted(event, None, None)
        if deviation is None:
            self.ideal_grip(opening_m)
        else:
            deviation.apply(self, opening_m)

    # --- what scoring reads (trial.runner.Bodies) ----------------------------------------
    @property
    def ticks(self) -> int:
        """The simulation ticks the moves would have taken."""
        return sum(move.motion.ticks for move in self.moves)

    def brick_pose(self, brick: int) -> tuple[Vec3, QuatXYZW]:
        pose = self.bricks[brick].pose
        return pose.position_m, pose.quat_xyzw

    def brick_velocity(self, brick: int) -> tuple[Vec3, Vec3]:
        return self.bricks[brick].velocity_mps, (0.0, 0.0, 0.0)

    # --- scripting ----------------------------------------------------------------------
    def script(self, stage: str, deviation: Deviation, times: float = 1) -> None:
        """Let ``deviation`` happen on the next ``times`` calls it rides on at ``stage``."""
        self._script.append(_Scripted(stage, deviation, times))

    def _scripted(
        self, event: Event, waypoint: WaypointProposal | None, stop: int | None
    ) -> Deviation | None:
        for entry in self._script:
            deviation = entry.deviation
            if (
                entry.times > 0
                and entry.stage == self.stage
                and deviation.event == event
                and (deviation.only is None or deviation.only(self, waypoint, stop))
            ):
                entry.times -= 1
                return deviation
        return None

    # --- ideal behaviour ----------------------------------------------------------------
    def ideal_move(self, waypoint: WaypointProposal, stop_on_contact: int | None) -> Motion:
        """Put the tool at the waypoint (UnreachableError if IK misses it), carrying the held
        brick; a guarded move stops where its brick touches what is under it."""
        target = Pose(position_m=waypoint.position_m, quat_xyzw=waypoint.quat_xyzw)
        stopped = False
        if stop_on_contact is not None and stop_on_contact == self.held:
            rise = self._support_top(self.held, self._carried(target)) - self._lowest(
                self._carried(target), self.held
            )
            stopped = rise >= -TOUCH_M
            if rise > 0.0:
                x, y, z = target.position_m
                target = target.model_copy(update={"position_m": (x, y, z + rise)})
        self.go(target, waypoint.path)
        return motion(self.tool, waypoint, converged=True, stopped_on_contact=stopped)

    def go(self, pose: Pose, path: str = "joint") -> None:
        """The tool at ``pose`` at once, the held brick with it (and settled in the hand).
        IK solves a joint move's end from the rest pose, a linear one's from where the arm
        is (as the real controller does, which solves it every centimetre)."""
        joints = self._solve(pose, self.joints if path == "linear" else None)
        for brick in self.bricks:
            brick.velocity_mps = (0.0, 0.0, 0.0)
        self.pads = {i: f for i, f in self.pads.items() if i == self.held}
        self.tool, self.joints = pose, joints
        if self.held is not None:
            self.bricks[self.held].pose = self._carried(pose)
            self._settle_in_hand()

    def ideal_grip(self, opening_m: float | None) -> None:
        """Close on the brick between the pads (centring it across them), or open to
        ``opening_m`` (no narrower than a brick held) and let go of it."""
        if opening_m is not None:
            if self.held is not None and opening_m <= self.bricks[self.held].size_m[1]:
                return  # the pads stay on the brick they hold
            self.width, self.pads = opening_m, {}
            if self.held is not None:
                released, self.held = self.held, None
                self._fall(released)
            return
        brick = self._between_pads()
        if brick is None:
            self.width = GRIPPER_GAP_M[0]
            return
        offset = self.in_tool_frame(self.bricks[brick].pose.position_m)
        offset[1] = 0.0
        position = np.add(
            self.tool.position_m, Rotation.from_quat(self.tool.quat_xyzw).apply(offset)
        )
        self.bricks[brick].pose = self.bricks[brick].pose.model_copy(
            update={"position_m": tuple(float(v) for v in position)}
        )
        self.hold(brick, (GRIP_N, GRIP_N))

    def hold(self, brick: int, normal_n: tuple[float, float]) -> None:
        """Brick ``brick`` held as it is now, pressed with ``normal_n`` by the pads."""
        self.held = brick
        self.width = self.bricks[brick].size_m[1]
        self.pads = {brick: normal_n}
        pose = self.bricks[brick].pose
        tool = Rotation.from_quat(self.tool.quat_xyzw)
        self._grip = (
            self.in_tool_frame(pose.position_m),
            tool.inv() * Rotation.from_quat(pose.quat_xyzw),
        )

    def turn_in_hand(self, turn: Rotation, shift_m: Vec3 = (0.0, 0.0, 0.0)) -> None:
        """The held brick turned by ``turn`` about the tool centre point and moved by
        ``shift_m``, both in the tool frame (x along the pads, y across, z down)."""
        offset, rotation = self._grip
        self._grip = (turn.apply(offset) + np.asarray(shift_m), turn * rotation)
        assert self.held is not None
        self.bricks[self.held].pose = self._carried(self.tool)

    def push(self, brick: int, shift_m: Vec3) -> None:
        """A loose brick moved by ``shift_m`` (world frame)."""
        pose = self.bricks[brick].pose
        position = tuple(float(v) for v in np.add(pose.position_m, shift_m))
        self.bricks[brick].pose = pose.model_copy(update={"position_m": position})

    def nearest_brick(self) -> int:
        """The brick whose centre is nearest the tool centre point."""
        return min(
            range(len(self.bricks)),
            key=lambda i: math.dist(self.bricks[i].pose.position_m, self.tool.position_m),
        )

    def in_tool_frame(self, position_m: Vec3) -> np.ndarray:
        return self._tool_turn.inv().apply(np.subtract(position_m, self.tool.position_m))

    @property
    def _tool_turn(self) -> Rotation:
        return Rotation.from_quat(self.tool.quat_xyzw)

    # --- kinematics ---------------------------------------------------------------------
    def _solve(self, pose: Pose, seed: tuple[float, ...] | None) -> tuple[float, ...]:
        solution = self.arm.solve(pose.position_m, pose.quat_xyzw, seed)
        if not solution.reached:
            x, y, z = pose.position_m
            raise UnreachableError(f"pose ({x:.3f}, {y:.3f}, {z:.3f}) m is out of reach")
        return solution.joints_rad

    def _carried(self, tool: Pose) -> Pose:
        offset, rotation = self._grip
        turn = Rotation.from_quat(tool.quat_xyzw)
        position = np.add(tool.position_m, turn.apply(offset))
        return Pose(
            position_m=tuple(float(v) for v in position),
            quat_xyzw=tuple(float(q) for q in (turn * rotation).as_quat()),
        )

    def _settle_in_hand(self) -> None:
        """A held brick carried into what is under it turns level and slides up the pads."""
        assert self.held is not None
        brick = self.bricks[self.held]
        below = self._support_top(self.held, brick.pose) - self._lowest(brick.pose, self.held)
        if below <= TOUCH_M:
            return
        x, y, _ = brick.pose.position_m
        level = _level(brick.pose.quat_xyzw)
        top = self._support_top(self.held, brick.pose)
        brick.pose = Pose(position_m=(x, y, top + brick.size_m[2] / 2.0), quat_xyzw=level)
        self.hold(self.held, self.pads[self.held])

    def _fall(self, brick: int) -> None:
        """A brick let go of falls flat onto what is under it."""
        body = self.bricks[brick]
        x, y, _ = body.pose.position_m
        top = self._support_top(brick, body.pose)
        body.pose = Pose(
            position_m=(x, y, top + body.size_m[2] / 2.0), quat_xyzw=_level(body.pose.quat_xyzw)
        )

    def _lowest(self, pose: Pose, brick: int) -> float:
        """Height of the lowest corner of brick ``brick`` at ``pose``."""
        half = np.asarray(self.bricks[brick].size_m) / 2.0
        signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        corners = Rotation.from_quat(pose.quat_xyzw).apply(signs * half)
        return float(pose.position_m[2] + corners[:, 2].min())

    def _support_top(self, brick: int, pose: Pose) -> float:
        """The highest top face under brick ``brick`` at ``pose``: the ground or a brick
        below it whose footprint overlaps its own."""
        mine = _footprint(pose, self.bricks[brick].size_m)
        tops = [
            b.pose.position_m[2] + b.size_m[2] / 2.0
            for i, b in enumerate(self.bricks)
            if i != brick
            and b.pose.position_m[2] < pose.position_m[2]
            and mine.intersection(_footprint(b.pose, b.size_m)).area > 1e-6
        ]
        return max(tops, default=0.0)

    def _between_pads(self) -> int | None:
        """The brick the closing pads meet: across its width, within the pads' reach."""
        tool_yaw = quat_yaw(self.tool.quat_xyzw)
        for i, brick in enumerate(self.bricks):
            x, y, z = self.in_tool_frame(brick.pose.position_m)
            length, width, height = brick.size_m
            # Modulo a half turn: the pads grip a brick turned 180 deg the same.
            turn = abs(wrap_angle(2.0 * (quat_yaw(brick.pose.quat_xyzw) - tool_yaw))) / 2.0
            if (
                abs(x) <= length / 2.0
                and abs(y) <= (self.width - width) / 2.0 + 1e-9
                and abs(z) <= height / 2.0
                and turn <= math.radians(GRASP_YAW_DEG)
            ):
                return i
        return None

    def _tangential(self, brick: int | None) -> tuple[float, float]:
        """The friction each pad carries of a held brick: half its weight."""
        if brick is None or brick != self.held:
            return (0.0, 0.0)
        share = self.mass_kg * GRAVITY_MPS2 / 2.0
        return (share, share)

    def _status(self, brick: int, progress: Progress) -> BrickStatus:
        pose = self.bricks[brick].pose
        x, y, z = pose.position_m
        if brick == self.held:
            return BrickStatus.GRASPED
        if tilt_deg(pose.quat_xyzw) > TOPPLED_DEG:
            return BrickStatus.TOPPLED
        if brick in progress.placed_ids:
            return BrickStatus.PLACED
        radius, azimuth = math.hypot(x, y), math.degrees(math.atan2(y, x))
        (r_low, r_high), (a_low, a_high) = self.spec.pick_radius_m, self.spec.pick_azimuth_deg
        on_ground = z < self.bricks[brick].size_m[2]
        if r_low <= radius <= r_high and a_low <= azimuth <= a_high and on_ground:
            return BrickStatus.IN_PICK_AREA
        return BrickStatus.DROPPED


def motion(
    reached: Pose,
    waypoint: WaypointProposal,
    converged: bool = True,
    stopped_on_contact: bool = False,
) -> Motion:
    """The report of a move that ended at ``reached``, sent to ``waypoint``."""
    turn = Rotation.from_quat(reached.quat_xyzw).inv() * Rotation.from_quat(waypoint.quat_xyzw)
    return Motion(
        ticks=round((waypoint.duration_s or 0.0) / TICK_S),
        converged=converged,
        stopped_on_contact=stopped_on_contact,
        position_error_m=math.dist(reached.position_m, waypoint.position_m),
        orientation_error_deg=math.degrees(turn.magnitude()),
    )


def _level(quat_xyzw: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    return yaw_quat(quat_yaw(quat_xyzw))


def _footprint(pose: Pose, size_m: Vec3) -> Polygon:
    return Box(pose.position_m, pose.quat_xyzw, size_m).footprint


# --- deviations ---------------------------------------------------------------------------
def _lifting(world: FakeWorld, waypoint: WaypointProposal | None, stop: int | None) -> bool:
    """A move that raises a held brick by more than 5 cm (a lift, not a put-back)."""
    return (
        world.held is not None
        and waypoint is not None
        and waypoint.position_m[2] > world.tool.position_m[2] + 0.05
    )


def _guarded(world: FakeWorld, waypoint: WaypointProposal | None, stop: int | None) -> bool:
    return stop is not None


def _holding_still(world: FakeWorld, waypoint: WaypointProposal | None, stop: int | None) -> bool:
    """A move that keeps a held brick where the tool is (the orchestrator's hold to let a
    swing die out)."""
    return (
        world.held is not None
        and waypoint is not None
        and math.dist(waypoint.position_m, world.tool.position_m) < 1e-9
    )


def slips(speed_mps: float = 0.02, drop_m: float = 0.01, settles: bool = False) -> Deviation:
    """On a lift, the brick slides ``drop_m`` down the pads and is still sliding; held still
    after it, it keeps sliding at that speed, unless it ``settles`` (a swing that dies out)."""

    def sliding(world: FakeWorld) -> None:
        assert world.held is not None
        world.bricks[world.held].velocity_mps = (0.0, 0.0, -speed_mps)

    def hold(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        sliding(world)
        return done

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        world.turn_in_hand(Rotation.identity(), (0.0, 0.0, drop_m))
        sliding(world)
        if not settles and world.stage is not None:
            world.script(world.stage, Deviation("move", hold, only=_holding_still))
        return done

    return Deviation("move", apply, only=_lifting)


def rolls(degrees: float) -> Deviation:
    """On a move with a brick in the hand, it rolls ``degrees`` about the pads' axis."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        world.turn_in_hand(Rotation.from_euler("y", degrees, degrees=True))
        return done

    return Deviation("move", apply, only=lambda world, *_: world.held is not None)


def creeps(rate_deg_s: float) -> Deviation:
    """With a brick in the hand, every move rolls it about the pads' axis at ``rate_deg_s``
    for as long as the move takes (its duration_s, else a second): the creep of a brick
    hanging from the pads. Scripted with ``times=math.inf``, it rides every such move."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        world.turn_in_hand(
            Rotation.from_euler("y", rate_deg_s * (waypoint.duration_s or 1.0), degrees=True)
        )
        return world.ideal_move(waypoint, stop)

    return Deviation("move", apply, only=lambda world, *_: world.held is not None)


def lands_off(shift_m: Vec3, turn_deg: float = 0.0, tilt_deg: float = 0.0) -> Deviation:
    """On a set-down, the brick touches down and slides ``shift_m`` (world frame) in the
    hand, turning ``turn_deg`` about the vertical through its centre and tipping
    ``tilt_deg`` about its length (it does not sit flat)."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        assert world.held is not None
        brick = world.bricks[world.held]
        brick.pose = _moved(brick.pose, shift_m, turn_deg, tilt_deg)
        world.hold(world.held, world.pads[world.held])
        return done

    return Deviation("move", apply, only=_guarded)


def falls_out(shift_m: Vec3) -> Deviation:
    """On a set-down, the brick slips out of the pads and lands flat ``shift_m`` (world
    frame) off where it was carried, and the pads close on nothing."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        assert world.held is not None
        brick = world.bricks[world.held]
        x, y, _ = brick.pose.position_m
        flat = (x + shift_m[0], y + shift_m[1], brick.size_m[2] / 2.0)
        brick.pose = Pose(position_m=flat, quat_xyzw=_level(brick.pose.quat_xyzw))
        world.held, world.pads = None, {}
        return done

    return Deviation("move", apply, only=_guarded)


def closes_off(shift_m: tuple[float, float], turn_deg: float = 0.0) -> Deviation:
    """Closing, the pads leave the brick held ``shift_m`` (world x, y) off the tool centre
    point and turned ``turn_deg`` about the vertical (a grip that pulled the brick along)."""

    def apply(world: FakeWorld, opening_m: float | None) -> None:
        world.ideal_grip(opening_m)
        assert world.held is not None, "nothing between the pads to close on"
        brick = world.bricks[world.held]
        brick.pose = _moved(brick.pose, (*shift_m, 0.0), turn_deg)
        world.hold(world.held, world.pads[world.held])

    return Deviation("close", apply)


def lets_go_off(shift_m: tuple[float, float]) -> Deviation:
    """Opening, the pads let the brick go and it ends ``shift_m`` (world x, y) off where it
    was set (a brick the release dragged along)."""

    def apply(world: FakeWorld, opening_m: float | None) -> None:
        released = world.held
        world.ideal_grip(opening_m)
        if released is not None and world.held is None:
            brick = world.bricks[released]
            brick.pose = _moved(brick.pose, (*shift_m, 0.0), 0.0)

    return Deviation("open", apply)


def _moved(pose: Pose, shift_m: Vec3, turn_deg: float, tilt_deg: float = 0.0) -> Pose:
    """``pose`` moved by ``shift_m`` (world frame), turned ``turn_deg`` about the vertical
    through its centre and tipped ``tilt_deg`` about its own x axis (its length)."""
    turn = (
        Rotation.from_euler("z", turn_deg, degrees=True)
        * Rotation.from_quat(pose.quat_xyzw)
        * Rotation.from_euler("x", tilt_deg, degrees=True)
    )
    return Pose(
        position_m=tuple(float(v) for v in np.add(pose.position_m, shift_m)),
        quat_xyzw=tuple(float(q) for q in turn.as_quat()),
    )


def shoves(along_m: float) -> Deviation:
    """On a move, a pad catches the brick nearest the tool and pushes it ``along_m`` along
    its length."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        brick = world.nearest_brick()
        yaw = quat_yaw(world.bricks[brick].pose.quat_xyzw)
        world.push(brick, (along_m * math.cos(yaw), along_m * math.sin(yaw), 0.0))
        return done

    return Deviation("move", apply)


def presses(force_n: float) -> Deviation:
    """On a move, one pad comes to press on the brick nearest the tool with ``force_n``
    (until the next move)."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        done = world.ideal_move(waypoint, stop)
        world.pads[world.nearest_brick()] = (force_n, 0.0)
        return done

    return Deviation("move", apply)


def stalls(short_m: float) -> Deviation:
    """A move that does not converge: it ends ``short_m`` before its waypoint."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        start, end = np.asarray(world.tool.position_m), np.asarray(waypoint.position_m)
        direction = (end - start) / max(float(np.linalg.norm(end - start)), 1e-9)
        reached = tuple(float(v) for v in end - short_m * direction)
        world.go(Pose(position_m=reached, quat_xyzw=waypoint.quat_xyzw), waypoint.path)
        return motion(world.tool, waypoint, converged=False)

    return Deviation("move", apply)


def out_of_reach() -> Deviation:
    """A move whose waypoint IK does not reach: nothing moves."""

    def apply(world: FakeWorld, waypoint: WaypointProposal, stop: int | None) -> Motion:
        x, y, z = waypoint.position_m
        raise UnreachableError(f"pose ({x:.3f}, {y:.3f}, {z:.3f}) m is out of reach")

    return Deviation("move", apply)


def one_pad_misses() -> Deviation:
    """Closing, only one pad meets the brick: it is touched, not held."""

    def apply(world: FakeWorld, opening_m: float | None) -> None:
        world.ideal_grip(opening_m)
        brick = world.held
        assert brick is not None, "nothing between the pads to miss"
        world.held = None
        world.pads = {brick: (GRIP_N, 0.0)}

    return Deviation("close", apply)
