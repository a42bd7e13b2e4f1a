"""What an agent is shown of the world: the parts of S_t its decision needs.

A :class:`StateView` is read from the measured :class:`WorldState` and is the state block of
every prompt. It leaves out what no decision reads (joint angles, velocities: the tools
measure motion; built targets, which memory lists) and, for agents 2-6, the bricks far
from the current brick and its target.
The built-in reasoner reads this same view, and the prompt-only reference model parses it
back from the prompt's text, so neither knows more than a language model is told.
"""

from __future__ import annotations

import math
from enum import StrEnum

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.agents.memory import TaskMemory
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import Vec3
from actionreasoning.world.models import (
    BrickState,
    BrickStatus,
    GoalPattern,
    Pose,
    Sensing,
    Supply,
    WorldState,
    is_pickable,
    nearest_size,
)
from actionreasoning.world.support import carriers

#: Agents 2-6 are shown the bricks within this distance (m, in the plane) of the current
#: brick or its target, and any brick neither in the pick area nor placed.
NEAR_M = 0.25


class Scope(StrEnum):
    """Which bricks and targets an agent is shown."""

    PICK = "pick"  # agent 1: the unplaced bricks and the targets not built
    ALL = "all"  # the single agent: every brick, the targets not built
    BRICK = "brick"  # agents 2, 3, 6: the current target; bricks within NEAR_M of the
    # current brick, and any dropped, toppled or grasped
    PATH = "path"  # agents 4, 5: the same, and the bricks within NEAR_M of the target


class _View(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid")


class RobotView(_View):
    """The tool and gripper."""

    tool_pose: Pose = Field(description="Tool centre point, between the finger pads.")
    gripper_width_m: float = Field(description="Gap between the pads.")
    pad_forces_n: tuple[float, float] | None = Field(
        None, description="Normal force of a held brick per pad (agents that grip)."
    )
    ready_pose: Pose | None = Field(
        None, description="Where the tool returns to after each brick (agents that return)."
    )


class BrickView(_View):
    """One brick as measured."""

    id: int
    size_m: Vec3
    pose: Pose
    status: BrickStatus

    @property
    def pickable(self) -> bool:
        """Free to be picked: in the pick area, or dropped and lying flat (:func:`is_pickable`)."""
        return is_pickable(self.status)

    @property
    def top_m(self) -> float:
        """Height of its top face if it lies flat."""
        return self.pose.position_m[2] + self.size_m[2] / 2.0


class TargetView(_View):
    """One target of the pattern, in build order."""

    index: int
    pose: Pose
    rests_on: tuple[int, ...] = Field(description="Targets it stands on.")
    size_m: Vec3 | None = Field(
        None,
        description="The brick it takes, in a pattern of several brick sizes: a brick is of "
        "the size its edges are nearest to.",
    )


class StateView(_View):
    """The state block of a prompt."""

    robot: RobotView
    bricks: tuple[BrickView, ...] = Field(
        (), description="The bricks as measured; absent in the image tier, which shows none."
    )
    targets: tuple[TargetView, ...]
    sensing: Sensing | None = Field(None, description="Sensor noise; absent when exact.")
    supply: Supply | None = Field(
        None, description="Where the bricks wait: pallet or feeder; absent when scattered."
    )

    def brick(self, brick_id: int) -> BrickView:
        """The brick ``brick_id`` (KeyError if it is not shown)."""
        for brick in self.bricks:
            if brick.id == brick_id:
                return brick
        raise KeyError(f"brick {brick_id} is not in the state")

    def fits(self, brick: BrickView, target: int) -> bool:
        """Whether ``brick`` is of the size target ``target`` takes (always, in a pattern of
        one brick size, whose targets show none)."""
        sizes = [t.size_m for t in self.targets if t.size_m is not None]
        wanted = next(t.size_m for t in self.targets if t.index == target)
        return wanted is None or nearest_size(brick.size_m, sizes) == wanted

    @classmethod
    def of(
        cls,
        state: WorldState,
        memory: TaskMemory,
        scope: Scope,
        extras: tuple[str, ...] = (),
        poses: bool = True,
    ) -> StateView:
        """The view of ``state`` an agent of ``scope`` is shown (see :class:`Scope`), with
        the robot fields ``extras`` (pad_forces_n, ready_pose) if it needs them. Without
        ``poses`` (the image tier) it shows no brick, and each target with the size of brick
        it takes, agents 1 and 0 every target, built or not: the goal, which no picture
        shows, and where the built bricks stand."""
        robot = state.robot
        supports = target_supports(state.goal)
        built = {p.target_index for p in memory.placed}
        placed = {p.brick_id for p in memory.placed}
        targets = [
            TargetView(
                index=t.index,
                pose=t.pose,
                rests_on=supports[t.index],
                size_m=t.size_m if len(state.goal.sizes) > 1 or not poses else None,
            )
            for t in state.goal.targets
            if (
                t.index not in built or not poses
                if scope in (Scope.PICK, Scope.ALL)
                else t.index == memory.current_target
            )
        ]
        centres = [b.pose.position_m for b in state.bricks if b.id == memory.current_brick]
        if scope is Scope.PATH:
            centres += [t.pose.position_m for t in targets]

        def shown(brick: BrickState) -> bool:
            if brick.status is BrickStatus.QUEUED or not poses:
                return False
            if scope is Scope.ALL:
                return True
            if scope is Scope.PICK:
                return brick.id not in placed
            near = any(math.dist(brick.pose.position_m[:2], c[:2]) <= NEAR_M for c in centres)
            return near or brick.status not in (BrickStatus.IN_PICK_AREA, BrickStatus.PLACED)

        return cls(
            robot=RobotView(
                tool_pose=robot.ee_pose,
                gripper_width_m=robot.gripper_width_m,
                pad_forces_n=robot.finger_forces_n if "pad_forces_n" in extras else None,
                ready_pose=robot.ready_pose if "ready_pose" in extras else None,
            ),
            bricks=tuple(
                BrickView(id=b.id, size_m=b.size_m, pose=b.pose, status=b.status)
                for b in state.bricks
                if shown(b)
            ),
            targets=tuple(targets),
            sensing=None if state.sensing == Sensing() else state.sensing,
            supply=None if state.goal.supply is Supply.SCATTERED else state.goal.supply,
        )


def target_supports(goal: GoalPattern) -> dict[int, tuple[int, ...]]:
    """For each target, the targets it rests on."""
    boxes = [Box(t.pose.position_m, t.pose.quat_xyzw, t.size_m, id=t.index) for t in goal.targets]
    return {box.named_id: tuple(o.named_id for o, _ in carriers(box, boxes)) for box in boxes}
