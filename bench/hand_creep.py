"""How fast a held brick of each catalogue size creeps in the hand, at rest, per profile.

    .venv/bin/python bench/hand_creep.py --grasps 8
    .venv/bin/python bench/hand_creep.py --physics precise

A brick of the size lies alone in the pick area (run seed 1, trial k); it is grasped
top-down at its centre, lifted straight up to 0.30 m at the controller's limit, and held
still for ``HOLD_S``. Measured in the tool frame: the roll (deg/s) and the speed of the
brick's centre (mm/s) over the hold, mean and largest over the grasps, against sigma_4's
v_th (the slip speed a brick must stay under to be carried on).
"""

from __future__ import annotations

import argparse

import numpy as np
from profiles import change, in_hand
from rich.console import Console
from rich.table import Table

from actionreasoning.control.waypoint import GripperCommand, Waypoint
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.models import GoalPattern, Pose
from actionreasoning.world.pattern_file import PatternFile
from actionreasoning.world.patterns import place_pattern
from actionreasoning.world.scenarios import load_physics
from actionreasoning.world.scene_spec import BRICK_CATALOGUE, SceneSpec
from actionreasoning.world.tolerances import Tolerances

RUN_SEED = 1
LIFT_Z = 0.30
HOLD_S = 10.0
OPENING_M = 0.135


def one_brick(name: str) -> GoalPattern:
    """A pattern of one catalogue brick ``name`` on the ground in the build area."""
    height = BRICK_CATALOGUE[name][2]
    pattern = PatternFile.model_validate(
        {"name": name, "brick_size": name, "bricks": [{"position": [0, 0, height / 2]}]}
    )
    return place_pattern(pattern, f"one {name} brick", SceneSpec())


def creep(goal: GoalPattern, physics: str, trial: int) -> tuple[float, float]:
    """Roll (deg/s) and centre speed (mm/s) of brick 0 in the hand over the hold."""
    config = TrialConfig(physics=load_physics(physics))
    spec = TrialSpec(Method.AGENTS, goal.name, goal, RUN_SEED, trial, config)
    with trial_world(spec) as world:
        scene, controller = world.scene, world.controller
        (x, y, z), quat = scene.brick_pose(0)
        tool = top_down_quat(quat_yaw(quat))
        controller.execute(
            Waypoint(
                pose=Pose(position_m=(x, y, 0.15), quat_xyzw=tool),
                gripper=GripperCommand.OPEN,
                gripper_opening_m=OPENING_M,
            )
        )
        controller.execute(Waypoint(pose=Pose(position_m=(x, y, z), quat_xyzw=tool), path="linear"))
        controller.grip(GripperCommand.CLOSE)
        controller.execute(
            Waypoint(pose=Pose(position_m=(x, y, LIFT_Z), quat_xyzw=tool), path="linear")
        )
        before = in_hand(scene)
        scene.step(scene.ticks_for(HOLD_S))
        moved_mm, turned_deg = change(before, in_hand(scene))
        return turned_deg / HOLD_S, moved_mm / HOLD_S


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grasps", type=int, default=8)
    parser.add_argument("--physics", default="paper")
    args = parser.parse_args()
    v_th = Tolerances.derive().v_th_mps * 1000.0
    table = Table(title=f"A held brick at rest, {args.physics} physics, {args.grasps} grasps")
    for column in ("brick", "roll (deg/s)", "max", "centre speed (mm/s)", "max", "v_th (mm/s)"):
        table.add_column(column, justify="right")
    for name in BRICK_CATALOGUE:
        goal = one_brick(name)
        rates = np.array([creep(goal, args.physics, k) for k in range(args.grasps)])
        table.add_row(
            name,
            f"{rates[:, 0].mean():.2f}",
            f"{rates[:, 0].max():.2f}",
            f"{rates[:, 1].mean():.2f}",
            f"{rates[:, 1].max():.2f}",
            f"{v_th:.2f}",
        )
    Console().print(table)


if __name__ == "__main__":
    main()
