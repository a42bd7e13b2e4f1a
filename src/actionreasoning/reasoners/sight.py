"""The image tier's eyes for the built-in policy: the bricks an image-tier prompt's pictures
show, as the state block of the state tier would list them.

An image-tier state block holds the robot and the targets but no brick. The policy reads
bricks from a :class:`~actionreasoning.agents.view.StateView`, so :func:`seen_view` fills
one in from the pictures and the memory alone:

- **Free bricks**: the bricks the depth cameras' pictures show (``brick_finder.py``), each
  of the target size whose footprint it fits, lying flat under its top face; a find on a
  built target (memory.placed), at that target's height, is the brick placed there and is
  left out, as the state block leaves out placed bricks. Found bricks are numbered from
  :data:`SEEN_ID_BASE`, ids no brick of the scene has: the policy never sends them back,
  since agent 1 names its brick by where it lies. A find on a target not yet built (a
  brick set down off its slot, left there) is in that target's way and numbered first, so
  that the policy picks it first, as the state tier's policy picks first the brick a
  refusal found in the way.
- **The current brick** (memory.current_brick, once this cycle's agent 1 has chosen it)
  lies under the tool until it is grasped: agent 1 moved the tool over its centre, agent 2
  down to it, turned as the tool is (the pads close across its width); its height that of
  the top face the pictures show there (the ground's, if they show none: the arm over it
  can hide a brick on a stack from every camera); shifted, in height too, by what the
  refusals of a descent in a row measured of it. Held, it sits between the pads,
  squared to them (closing, they square it), rolled about their axis and shifted as its
  points in the depth pictures lie, the roll as the gates measured it over the slot once
  they have; turned half round where the placement plan's refusals say.
- **A brick put down** for a re-grasp (memory.regrasps, before this cycle's agent 1 has
  chosen again) that the pictures do not show within its length of the tool lies under the
  tool, turned as the tool is: the arm let go of it there, pressed flat between the pads,
  and rose straight up over it, which hides it from above (and often from the side).
  Where it lies off that, the pre-grasp gate's refusals measure it (:func:`corrected`);
  where agent 1's approach over it was refused for finding no brick there (it fell or
  rolled away on the way down), it is not taken to be there again: it is among the finds,
  if the pictures show it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import takewhile

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from actionreasoning.agents.feedback import Refusal, since_put_down
from actionreasoning.agents.memory import StepDecision, TaskMemory
from actionreasoning.agents.view import BrickView, StateView, TargetView
from actionreasoning.reasoners.brick_finder import (
    MIN_PIXELS,
    SAME_BRICK_M,
    SeenBrick,
    brick_coloured,
    find_bricks,
    merged,
)
from actionreasoning.tools import formulas
from actionreasoning.world.geometry import Vec3, quat_yaw, top_down_quat, yaw_quat
from actionreasoning.world.models import BrickStatus, Pose
from actionreasoning.world.pictures import CAMERAS, Picture, PictureKind, read_colour, read_depth
from actionreasoning.world.stages import Stage

#: The first id of a brick found in the pictures: above any id of a scene's bricks.
SEEN_ID_BASE = 1000


def is_seen(brick_id: int) -> bool:
    """Whether ``brick_id`` numbers a brick found in the pictures (not one of the scene's)."""
    return brick_id >= SEEN_ID_BASE


def seen_view(view: StateView, memory: TaskMemory, pictures: Sequence[Picture]) -> StateView:
    """``view``, an image-tier state block, with the bricks its pictures show (see the
    module): the free ones, and the current brick under its own id."""
    sizes = [t.size_m for t in view.targets if t.size_m is not None]
    if not sizes:
        raise ValueError("the state shows no target's brick size: no brick can be found")
    finds = _finds(pictures, sizes)
    current = _current(view, memory, finds, sizes, pictures) or _put_down(view, memory, finds)
    built = _built(view, memory)
    free = [
        find
        for find in finds
        if not any(_on(find, target) for target in built)
        and (current is None or _apart(find, current.pose.position_m))
    ]
    # A brick lying on a target not yet built is in its way: numbered first, picked first.
    unbuilt = [t for t in view.targets if t not in built]
    free.sort(key=lambda find: not any(_on(find, target) for target in unbuilt))
    bricks = [_brick(SEEN_ID_BASE + number, find, sizes) for number, find in enumerate(free)]
    return view.model_copy(update={"bricks": (*([current] if current else []), *bricks)})


def _finds(pictures: Sequence[Picture], sizes: Sequence[Vec3]) -> list[SeenBrick]:
    """One find per brick over every camera that sent colour and depth."""
    footprints = sorted({(size[0], size[1]) for size in sizes})
    finds: list[SeenBrick] = []
    for colour, depth in _depth_pairs(pictures):
        rgb, metres = read_colour(colour.png), read_depth(depth.png)
        finds += find_bricks(rgb, metres, CAMERAS[depth.camera], footprints)
    return merged(finds)


def _brick(brick_id: int, find: SeenBrick, sizes: Sequence[Vec3]) -> BrickView:
    """A find as a free brick of the size whose footprint it was fitted with, lying flat."""
    size = next(s for s in sizes if (s[0], s[1]) == (find.length_m, find.width_m))
    x, y, top = find.top_centre_m
    pose = Pose(position_m=(x, y, top - size[2] / 2.0), quat_xyzw=yaw_quat(find.yaw_rad))
    return BrickView(id=brick_id, size_m=size, pose=pose, status=BrickStatus.IN_PICK_AREA)


def _built(view: StateView, memory: TaskMemory) -> list[TargetView]:
    """The targets memory lists as built, as the state block shows them."""
    built = {p.target_index for p in memory.placed}
    return [t for t in view.targets if t.index in built]


def _on(find: SeenBrick, target: TargetView) -> bool:
    """Whether a find is the brick on ``target``: within SAME_BRICK_M of it in the plane,
    its top within half the brick's height of the target's top."""
    x, y, z = target.pose.position_m
    height = target.size_m[2] if target.size_m is not None else 0.0
    near = math.dist(find.top_centre_m[:2], (x, y)) < SAME_BRICK_M
    return near and abs(find.top_centre_m[2] - (z + height / 2.0)) < height / 2.0


def _apart(find: SeenBrick, position_m: Vec3) -> bool:
    return math.dist(find.top_centre_m[:2], position_m[:2]) >= SAME_BRICK_M


def _current(
    view: StateView,
    memory: TaskMemory,
    finds: Sequence[SeenBrick],
    sizes: Sequence[Vec3],
    pictures: Sequence[Picture],
) -> BrickView | None:
    """The current brick (see the module); None before this cycle's agent 1 has chosen
    one."""
    if memory.current_brick is None or _decision(memory, Stage.PRE_GRASP) is None:
        return None
    target = next((t for t in view.targets if t.index == memory.current_target), None)
    size = target.size_m if target is not None and target.size_m is not None else sizes[0]
    tool = view.robot.tool_pose
    if _decision(memory, Stage.GRASP) is not None:
        watch = memory.roll_watch
        roll, offset = _held_seen(tool, size, pictures, watch.now_deg if watch else None)
        square = _TURNED if _turned_round(memory) else _SQUARE
        quat = formulas.rolled_in_hand((0.0, 0.0, 0.0), square, roll)[1]
        pose = formulas.carried(tool, offset, quat)
        return BrickView(
            id=memory.current_brick, size_m=size, pose=pose, status=BrickStatus.GRASPED
        )
    x, y, _ = tool.position_m
    under = [f for f in finds if not _apart(f, (x, y, 0.0))]
    top = max((f.top_centre_m[2] for f in under), default=size[2])
    pose = Pose(position_m=(x, y, top - size[2] / 2.0), quat_xyzw=tool.quat_xyzw)
    pose = _corrected(pose, memory, f"{Stage.DESCENT}_plan")
    return BrickView(
        id=memory.current_brick, size_m=size, pose=pose, status=BrickStatus.IN_PICK_AREA
    )


def _put_down(view: StateView, memory: TaskMemory, finds: Sequence[SeenBrick]) -> BrickView | None:
    """The brick put down for a re-grasp, under the tool, where no find shows it (see the
    module); None if none was put down, agent 1 has chosen again, or the pictures show it."""
    brick = memory.current_brick
    placed = {p.brick_id for p in memory.placed}
    if (
        brick is None
        or brick in placed
        or not memory.regrasps
        or memory.this_brick
        or _missed_since_put_down(memory)
    ):
        return None
    target = next((t for t in view.targets if t.index == memory.current_target), None)
    if target is None or target.size_m is None:
        return None
    size, tool = target.size_m, view.robot.tool_pose
    x, y, _ = tool.position_m
    if any(math.dist(f.top_centre_m[:2], (x, y)) < size[0] for f in finds):
        return None
    pose = Pose(position_m=(x, y, size[2] / 2.0), quat_xyzw=yaw_quat(quat_yaw(tool.quat_xyzw)))
    return BrickView(id=brick, size_m=size, pose=pose, status=BrickStatus.DROPPED)


def _missed_since_put_down(memory: TaskMemory) -> bool:
    """Whether an approach of agent 1's since the last put-down was refused for finding no
    brick under it. The first approach after a put-down goes over the brick taken to lie
    under the tool, if the pictures show none near it: that refusal says it does not."""
    return any(
        r.gate == _CHOICE_GATE and any(c.name == _NOTHING_UNDER for c in r.failed)
        for r in since_put_down(memory.refusals)
    )


#: The pre-grasp choice's refusal of an approach over no brick (``orchestrator._named``).
_CHOICE_GATE = f"{Stage.PRE_GRASP}_choice"
_NOTHING_UNDER = "brick_under_approach"

#: A brick squared in the hand: level, its long side along the tool's x axis (the pads close
#: across its width, along the tool's y axis), as a quaternion in the tool frame.
_SQUARE = formulas.in_hand(
    Pose(position_m=(0.0, 0.0, 0.0), quat_xyzw=top_down_quat(0.0)),
    Pose(position_m=(0.0, 0.0, 0.0), quat_xyzw=yaw_quat(0.0)),
)[1]
#: The same brick turned half round: its ends look alike, only the gates tell them apart.
_TURNED = formulas.in_hand(
    Pose(position_m=(0.0, 0.0, 0.0), quat_xyzw=top_down_quat(0.0)),
    Pose(position_m=(0.0, 0.0, 0.0), quat_xyzw=yaw_quat(math.pi)),
)[1]
#: Gates that measure how the held brick would land turned (or landed).
_LANDING_GATES = (f"{Stage.PLACEMENT}_plan", "sigma5_placement")


def _turned_round(memory: TaskMemory) -> bool:
    """Whether the held brick is turned half round from how it looks (its +x end where
    its -x end seems to be): the pictures cannot tell its ends apart, and the rotation
    error is measured between the brick's frame and its target's. Each refusal since it was
    grasped whose gate measured its landing turned more than a quarter turn says the
    guess was wrong (the gates measure the brick's own frame): an odd number of them,
    turned."""
    wrong = sum(
        1 for r in since_put_down(memory.refusals) if r.gate in _LANDING_GATES and ends_swapped(r)
    )
    return wrong % 2 == 1


def ends_swapped(refusal: Refusal) -> bool:
    """Whether ``refusal`` measured a landing turned more than a quarter turn: the brick's
    ends the other way round from how it was taken to be held, not a yaw to correct."""
    return abs(refusal.measured.e_theta_deg or 0.0) > 90.0


#: The held brick's points: brick-coloured pixels within this of the tool centre point (m):
#: half the diagonal of the longest brick and a margin.
_HELD_WITHIN_M = 0.13
#: The rolls a fit starts from (deg): a brick rolls in the hand no further than onto its
#: side, and a fit started within 5 deg of the roll finds it.
_ROLLS_TRIED = np.arange(-90.0, 90.1, 5.0)


def _held_seen(
    tool: Pose, size_m: Vec3, pictures: Sequence[Picture], roll_deg: float | None = None
) -> tuple[float, Vec3]:
    """The held brick's roll about the pads' axis (deg, as the gates measure it) and its
    centre's offset (m) in the tool frame, from its points in the depth pictures: the box of
    its size, squared to the pads, so rolled and shifted that its visible points lie on its
    surface (robust least squares; a point off it is the gripper's or another brick's).
    With ``roll_deg`` (the gates' measurement) the roll is that and only the offset is
    fitted. No offset (and no roll, unless given) if too few of its points show."""
    points = []
    for colour, depth in _depth_pairs(pictures):
        camera = CAMERAS[depth.camera]
        metres = read_depth(depth.png)
        mask = brick_coloured(read_colour(colour.png)) & np.isfinite(metres)
        rows, cols = np.nonzero(mask)
        pixels = np.column_stack([cols, rows]).astype(float)
        world = camera.deproject_all(pixels, metres[rows, cols].astype(float))
        near = np.linalg.norm(world - np.asarray(tool.position_m), axis=1) <= _HELD_WITHIN_M
        points.append(world[near])
    held = np.concatenate(points) if points else np.empty((0, 3))
    if len(held) < MIN_PIXELS:
        return roll_deg or 0.0, (0.0, 0.0, 0.0)
    in_tool = Rotation.from_quat(tool.quat_xyzw).inv().apply(held - np.asarray(tool.position_m))
    half = np.asarray(size_m) / 2.0

    def off_surface(params: np.ndarray) -> np.ndarray:
        roll, *offset = params if roll_deg is None else (roll_deg, *params)
        turn = Rotation.from_euler("y", roll, degrees=True)
        outside = np.abs(turn.inv().apply(in_tool - offset)) - half
        return np.linalg.norm(np.maximum(outside, 0.0), axis=1) + np.minimum(
            outside.max(axis=1), 0.0
        )

    still = (0.0, 0.0, 0.0)
    starts = [still] if roll_deg is not None else [(r, *still) for r in _ROLLS_TRIED]
    fits = [least_squares(off_surface, x0, loss="soft_l1", f_scale=0.002) for x0 in starts]
    best = min(fits, key=lambda fit: fit.cost).x
    roll, x, y, z = best if roll_deg is None else (roll_deg, *best)
    # A box rolled half round is the same box: the roll within a quarter turn, as the gates
    # measure it (formulas.roll_in_hand_deg).
    return (float(roll) + 90.0) % 180.0 - 90.0, (float(x), float(y), float(z))


def _depth_pairs(pictures: Sequence[Picture]) -> list[tuple[Picture, Picture]]:
    """(colour, depth) of every camera that sent both."""
    colour = {p.camera: p for p in pictures if p.kind is PictureKind.COLOUR}
    return [
        (colour[p.camera], p)
        for p in pictures
        if p.kind is PictureKind.DEPTH and p.camera in colour and p.camera in CAMERAS
    ]


def corrected(view: StateView, brick_id: int, memory: TaskMemory) -> StateView | None:
    """``view`` with brick ``brick_id`` where the pre-grasp gate's refusals in a row, of
    approaches over it, measured it (``_corrected``); None if the last refusal is none of
    them, which leaves the view as it is."""
    gate = f"{Stage.PRE_GRASP}_plan"
    if not memory.refusals or memory.refusals[-1].gate != gate:
        return None
    bricks = tuple(
        b.model_copy(update={"pose": _corrected(b.pose, memory, gate)}) if b.id == brick_id else b
        for b in view.bricks
    )
    return view.model_copy(update={"bricks": bricks})


def _corrected(pose: Pose, memory: TaskMemory, gate: str) -> Pose:
    """A brick's ``pose`` as seen, corrected by the refusals in a row (the last ones) of
    ``gate``, each of an answer made from the pose as corrected by those before it: each
    measured the brick off that pose by (e_x, e_y, and e_z where the gate measures height:
    a descent's) and turned by e_theta (wanted minus measured: the brick minus the tool), so
    their sum is where the gate measures it."""
    trailing = list(takewhile(lambda r: r.gate == gate, reversed(memory.refusals)))
    x, y, z = pose.position_m
    dx, dy, dz = (
        sum(getattr(r.measured, axis) or 0.0 for r in trailing)
        for axis in ("e_x_m", "e_y_m", "e_z_m")
    )
    turn = sum(r.measured.e_theta_deg or 0.0 for r in trailing)
    yaw = quat_yaw(pose.quat_xyzw) + math.radians(turn)
    return Pose(position_m=(x + dx, y + dy, z + dz), quat_xyzw=yaw_quat(yaw))


def _decision(memory: TaskMemory, stage: Stage) -> StepDecision | None:
    """This brick's accepted decision of ``stage`` (the last, if several)."""
    return next((d for d in reversed(memory.this_brick) if d.agent == stage), None)
