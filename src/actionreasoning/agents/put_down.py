"""Putting a held brick down on the ground for a re-grasp: where, and how gently.

Where: on the nearest free ground where it can be grasped again (inside the arm's reach
band, clear of the other bricks and the unbuilt targets), so that a loose brick is not
carried far; in the image tier, also where the top-down picture shows all of it, since
agents shown no poses find a brick only in the pictures; back on the spot it was grasped
from if there is none. How: pressed
onto the ground, still held, until it lies flat, then let go just past its width. A brick
that rolled in the hand turns about the pads, which hold little torque: pressed down it
turns back flat, where one let go on a corner falls, often onto its side. Rolled so far
that its lowest edge is under its centre, pressed down it would tip onto its end: it is
laid level instead, the tool tilted by its roll, where the arm reaches that way down.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.spatial.transform import Rotation
from shapely.geometry import Polygon

from actionreasoning.agents.calls import AgentCaller
from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.agents.world import World
from actionreasoning.tools.collision import COLLISION, CollisionQuery
from actionreasoning.tools.formulas import in_hand, roll_in_hand_deg, slot_pose
from actionreasoning.tools.grasp_plan import GRASP_OPTIONS, GraspOptionsQuery
from actionreasoning.tools.placement import SEAT_CLEARANCE_M
from actionreasoning.world.boxes import Box
from actionreasoning.world.cameras import TOP_DOWN
from actionreasoning.world.geometry import Vec3, quat_yaw, top_down_quat, yaw_quat
from actionreasoning.world.ground import free_spots
from actionreasoning.world.models import BrickStatus, Pose, WorldState
from actionreasoning.world.scene_spec import GRIPPER_GAP_M, ReachBand

#: Mean speed of every move with a brick to put down, and the shortest move.
PUT_BACK_SPEED_MPS = 0.05
MIN_MOVE_S = 0.1
#: The opening that lets go of a brick put down: its width and this much.
PUT_DOWN_SLACK_M = 0.01
#: Where a brick is set aside: within this distance of the tool, this far from every other
#: brick and target (room for the open fingers and a loose brick's bounce), trying up to
#: this many spots, nearest first and this far apart, for one within reach and graspable.
SET_ASIDE_RANGE_M = 0.6
SET_ASIDE_MARGIN_M = 0.08
SET_ASIDE_CANDIDATES = 40
SET_ASIDE_SPREAD_M = 0.05
#: How far from its spot a brick put down may end up (seen: up to 10 cm, a brick rolled
#: 55 deg in the hand, which turns flat about its pivot on a pad rather than the tool).
SET_ASIDE_SLACK_M = 0.10
#: A brick swinging in the hand is measured again over its spot up to this many times,
#: until the place to press it flat from moves less than this.
PRESS_CHECKS = 3
PRESS_TOLERANCE_M = 0.005


class PutDown:
    """Puts the held brick down for a re-grasp, through the orchestrator's world and tools;
    ``in_sight``: only where the top-down picture shows all of it (agents shown no poses)."""

    def __init__(self, world: World, calls: AgentCaller, in_sight: bool = False) -> None:
        self.world = world
        self.calls = calls
        self.in_sight = in_sight

    def put_back(
        self, observe: Callable[[], WorldState], brick: int, spot: Pose, height: float
    ) -> None:
        """Set brick ``brick`` down flat with its centre on ``spot`` (the tool pose that
        grasps a brick lying there) and let go: up to ``height``, over the spot, down until
        the brick lies flat, open, and up again; all at PUT_BACK_SPEED_MPS. A loose brick
        swings on the way, so it is measured again over the spot until the tool is where it
        must be to press it flat. A brick no longer in the hand is left where it fell, and
        the open gripper goes up clear of it."""
        state = observe()
        held = state.brick(brick).status == BrickStatus.GRASPED
        if not held:
            self.world.grip(GRIPPER_GAP_M[1])
        width = state.brick(brick).size_m[1]
        x, y, z = state.robot.ee_pose.position_m
        height = max(z, height)
        self._gently(
            WaypointProposal(
                position_m=(x, y, height), quat_xyzw=state.robot.ee_pose.quat_xyzw, path="linear"
            ),
            height - z,
        )
        if not held or (_tips_onto_its_end(state, brick) and self._lay_level(observe, brick, spot)):
            return
        press = _pressing_point(state, brick, spot)
        for _ in range(PRESS_CHECKS):
            here = state.robot.ee_pose.position_m
            over = WaypointProposal(position_m=(*press[:2], height), quat_xyzw=spot.quat_xyzw)
            self._gently(over, math.dist(here[:2], press[:2]))
            state = observe()
            if state.brick(brick).status != BrickStatus.GRASPED:
                self.world.grip(GRIPPER_GAP_M[1])
                return
            again = _pressing_point(state, brick, spot)
            settled = math.dist(again[:2], press[:2]) <= PRESS_TOLERANCE_M
            press = again
            if settled:
                break
        down = WaypointProposal(position_m=press, quat_xyzw=spot.quat_xyzw, path="linear")
        self._gently(down, height - press[2])
        # Just past the brick's width: pads swung wide drag a loose brick over.
        self.world.grip(min(width + PUT_DOWN_SLACK_M, GRIPPER_GAP_M[1]))
        self.world.move(down.model_copy(update={"position_m": (*press[:2], height)}))

    def _lay_level(self, observe: Callable[[], WorldState], brick: int, spot: Pose) -> bool:
        """Lay the held brick level on ``spot`` by tilting the tool by its roll in the hand:
        over the spot (measured again there: the brick swings on the way), straight down
        until it touches the ground, open, and up again. False, with nothing moved, where the
        way down is out of reach or not clear."""
        state = observe()
        height = state.robot.ee_pose.position_m[2]
        for _ in range(PRESS_CHECKS):
            tool = _levelling_pose(state, brick, spot)
            x, y, z = tool.position_m
            over = WaypointProposal(position_m=(x, y, height), quat_xyzw=tool.quat_xyzw)
            seat = Pose(position_m=(x, y, z + SEAT_CLEARANCE_M), quat_xyzw=tool.quat_xyzw)
            query = CollisionQuery(
                pose=seat,
                start_pose=_as_pose(over),
                gripper_opening_m=state.robot.gripper_width_m,
            )
            way = self.calls.measure(state, COLLISION, query)
            if not (way.reachable and way.collision_free):
                return False
            here = state.robot.ee_pose.position_m
            self._gently(over, math.dist(here, over.position_m))
            state = observe()
            if state.brick(brick).status != BrickStatus.GRASPED:
                self.world.grip(GRIPPER_GAP_M[1])
                return True
            moved = math.dist(_levelling_pose(state, brick, spot).position_m, tool.position_m)
            if moved <= PRESS_TOLERANCE_M:
                break
        down = WaypointProposal(position_m=tool.position_m, quat_xyzw=tool.quat_xyzw, path="linear")
        seconds = max((height - z) / PUT_BACK_SPEED_MPS, MIN_MOVE_S)
        self.world.move(down.model_copy(update={"duration_s": seconds}), stop_on_contact=brick)
        width = state.brick(brick).size_m[1]
        self.world.grip(min(width + PUT_DOWN_SLACK_M, GRIPPER_GAP_M[1]))
        self._gently(over.model_copy(update={"path": "linear"}), height - z)
        return True

    def free_spot(
        self, state: WorldState, brick: int, target: int, built: set[int], height: float
    ) -> Pose | None:
        """The tool pose that grasps brick ``brick`` set down on the nearest free ground:
        clear of every other brick and every target not in ``built``, inside the arm's
        measured reach band and its base joint's turn (and, ``in_sight``, the top-down
        picture) with room for a landing off by SET_ASIDE_SLACK_M, reached on the way down
        from ``height``, and graspable there for ``target`` (a grasp that reaches the brick
        and the target)."""
        occupied = [_footprint(b.pose, b.size_m) for b in state.bricks if b.id != brick]
        occupied += [
            _footprint(t.pose, t.size_m) for t in state.goal.targets if t.index not in built
        ]
        held, tool = state.brick(brick), state.robot.ee_pose
        yaw = quat_yaw(tool.quat_xyzw)
        spots = free_spots(
            tool.position_m[:2],
            held.size_m,
            held.pose.quat_xyzw,
            occupied,
            SET_ASIDE_MARGIN_M,
            SET_ASIDE_RANGE_M,
            _seen_ground(held.size_m[2]) if self.in_sight else None,
        )
        band = ReachBand()
        low, high = band.min_radius_m + SET_ASIDE_SLACK_M, band.max_radius_m - SET_ASIDE_SLACK_M
        tried: list[tuple[float, float]] = []
        for x, y in spots:
            if len(tried) == SET_ASIDE_CANDIDATES:
                return None
            radius = math.hypot(x, y)
            # Room for the landing's slack within the base joint's turn, too.
            turn = abs(math.degrees(math.atan2(y, x))) + math.degrees(SET_ASIDE_SLACK_M / radius)
            if (
                not low <= radius <= high
                or turn > band.max_azimuth_deg
                or any(math.dist((x, y), t) < SET_ASIDE_SPREAD_M for t in tried)
            ):
                continue
            tried.append((x, y))
            spot = Pose(position_m=(x, y, held.size_m[2] / 2.0), quat_xyzw=top_down_quat(yaw))
            if self._way_down_reachable(state, spot, height, brick) and self._graspable(
                state, brick, target, spot, yaw
            ):
                return spot
        return None

    def _graspable(
        self, state: WorldState, brick: int, target: int, spot: Pose, yaw: float
    ) -> bool:
        """Whether a grasp of brick ``brick`` lying flat under ``spot`` (at ``yaw``) reaches
        it and ``target`` (``grasp_options`` on the world with the brick put there)."""
        lying = state.brick(brick).model_copy(
            update={
                "pose": Pose(position_m=spot.position_m, quat_xyzw=yaw_quat(yaw)),
                "status": BrickStatus.DROPPED,
            }
        )
        there = state.model_copy(
            update={"bricks": tuple(lying if b.id == brick else b for b in state.bricks)}
        )
        query = GraspOptionsQuery(brick_id=brick, target_index=target)
        options = self.calls.measure(there, GRASP_OPTIONS, query).options
        return any(option.reachable for option in options)

    def _way_down_reachable(self, state: WorldState, spot: Pose, height: float, brick: int) -> bool:
        """Every pose of the way straight down onto ``spot`` within reach (the held brick is
        left out of the check: it ends on the ground by design)."""
        x, y, _ = spot.position_m
        start = Pose(position_m=(x, y, height), quat_xyzw=spot.quat_xyzw)
        query = CollisionQuery(
            pose=spot,
            start_pose=start,
            gripper_opening_m=state.robot.gripper_width_m,
            ignore_brick_id=brick,
        )
        report = self.calls.measure(state, COLLISION, query)
        return bool(report.reachable)

    def _gently(self, move: WaypointProposal, length_m: float) -> None:
        seconds = max(length_m / PUT_BACK_SPEED_MPS, MIN_MOVE_S)
        self.world.move(move.model_copy(update={"duration_s": seconds}))


def _seen_ground(height_m: float) -> Polygon:
    """Where a brick's footprint may lie for the top-down picture to show all of its top
    face, at ``height_m``, after a landing off by up to SET_ASIDE_SLACK_M."""
    return Polygon(TOP_DOWN.view_at_height(height_m)).buffer(-SET_ASIDE_SLACK_M)


def _tips_onto_its_end(state: WorldState, brick: int) -> bool:
    """Whether the held brick has rolled so far in the hand that pressing it down would tip
    it onto its end rather than flat: its lowest edge is under its centre once the roll
    passes atan(length / height) (58 deg for a half brick, 73 for a full one), less the swing
    the press checks leave (PRESS_TOLERANCE_M at the brick's end)."""
    state_brick = state.brick(brick)
    length, _, height = state_brick.size_m
    _, turn = in_hand(state.robot.ee_pose, state_brick.pose)
    roll = abs(roll_in_hand_deg(turn))
    swing = math.degrees(PRESS_TOLERANCE_M / (length / 2.0))
    return roll > math.degrees(math.atan2(length, height)) - swing


def _levelling_pose(state: WorldState, brick: int, spot: Pose) -> Pose:
    """The tool pose that lays the held brick, as it sits in the hand, level with its centre
    on ``spot``: the tool turned by the least rotation that levels the brick (on either broad
    face), the brick's centre carried with it."""
    tool, held = state.robot.ee_pose, state.brick(brick).pose
    face = Rotation.from_quat(held.quat_xyzw).apply((0.0, 0.0, 1.0))
    level, _ = Rotation.align_vectors([(0.0, 0.0, 1.0)], [face if face[2] >= 0.0 else -face])
    target = Pose(
        position_m=spot.position_m,
        quat_xyzw=tuple(float(q) for q in (level * Rotation.from_quat(held.quat_xyzw)).as_quat()),
    )
    return slot_pose(target, *in_hand(tool, held))


def _as_pose(waypoint: WaypointProposal) -> Pose:
    return Pose(position_m=waypoint.position_m, quat_xyzw=waypoint.quat_xyzw)


def _pressing_point(state: WorldState, brick: int, spot: Pose) -> Vec3:
    """Where the tool must go, at the spot's orientation, so that the held brick, turned flat
    about the tool centre point, lies on the ground with its centre on ``spot``; no lower
    than a grasp of a brick lying there (a brick that slid up the pads is left a little
    tilted rather than the tool taken to the floor)."""
    flat = levelled_offset(state.robot.ee_pose, state.brick(brick).pose)
    x, y, z = np.subtract(spot.position_m, Rotation.from_quat(spot.quat_xyzw).apply(flat))
    return float(x), float(y), max(float(z), spot.position_m[2])


def levelled_offset(tool: Pose, brick: Pose) -> np.ndarray:
    """The brick's centre in the tool frame once it has turned flat about the tool centre
    point: its offset now, turned by the least rotation that lays it flat in the hand (on
    either broad face: a brick is the same upside down)."""
    to_tool = Rotation.from_quat(tool.quat_xyzw).inv()
    offset = to_tool.apply(np.subtract(brick.position_m, tool.position_m))
    face = (to_tool * Rotation.from_quat(brick.quat_xyzw)).apply((0.0, 0.0, 1.0))
    up = to_tool.apply((0.0, 0.0, 1.0))  # the world's up, in the tool frame
    turn, _ = Rotation.align_vectors([up], [face if np.dot(face, up) >= 0.0 else -face])
    return turn.apply(offset)


def _footprint(pose: Pose, size: tuple[float, float, float]) -> Polygon:
    return Box(pose.position_m, pose.quat_xyzw, size).footprint
