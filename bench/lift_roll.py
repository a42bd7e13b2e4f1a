"""How far a brick rolls in the hand, by lift speed and by carry speed (paper physics).

    .venv/bin/python bench/lift_roll.py --grasps 16

Brick 0 of pyramid trials (run seed 1, trial k) is grasped top-down at its centre, lifted
straight up to 0.30 m at each lift speed (and at the controller's limit), and, lifted at
the safe lift speed, carried in joint space to above the build area at each carry speed.
Counts, over the grasps, the lifts and the carries after which the brick had turned more
than 10 and 20 deg in the hand. ``SAFE_LIFT_MPS`` (``world/tolerances.py``) is the fastest
lift speed at which none turned more than 10 deg.
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from profiles import LIFT_Z, OVER_BUILD, RUN_SEED, change, in_hand

from actionreasoning.control.waypoint import GripperCommand, Waypoint
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import SAFE_LIFT_MPS

LIFT_SPEEDS = (0.01, 0.02, 0.03, 0.05, 0.1, None)
CARRY_SPEEDS = (0.05, 0.1, 0.2, 0.4, None)
OPENING_M = 0.135


def turns(trial: int, lift_mps: float | None, carry_mps: float | None) -> tuple[float, float]:
    """Turn of brick 0 in the hand (deg) after the lift, and during the carry (0: none)."""
    goal = load_pattern("pyramid", SceneSpec())
    spec = TrialSpec(Method.AGENTS, "pyramid", goal, RUN_SEED, trial, TrialConfig())
    with trial_world(spec) as world:
        scene, controller = world.scene, world.controller
        (x, y, z), quat = scene.brick_pose(0)
        tool = top_down_quat(quat_yaw(quat))

        def move(xyz: tuple[float, float, float], path: str = "joint", speed=None) -> None:
            here = scene.tcp_pose()[0]
            ticks = None if speed is None else scene.ticks_for(math.dist(here, xyz) / speed)
            pose = Pose(position_m=xyz, quat_xyzw=tool)
            controller.execute(Waypoint(pose=pose, path=path, min_ticks=ticks))

        controller.execute(
            Waypoint(
                pose=Pose(position_m=(x, y, 0.15), quat_xyzw=tool),
                gripper=GripperCommand.OPEN,
                gripper_opening_m=OPENING_M,
            )
        )
        move((x, y, z), path="linear")
        controller.grip(GripperCommand.CLOSE)
        grasped = in_hand(scene)
        move((x, y, LIFT_Z), path="linear", speed=lift_mps)
        lifted = in_hand(scene)
        if carry_mps == 0.0:
            return change(grasped, lifted)[1], 0.0
        move(OVER_BUILD, speed=carry_mps)
        return change(grasped, lifted)[1], change(lifted, in_hand(scene))[1]


def report(label: str, speed: float | None, turned: np.ndarray) -> None:
    name = "the controller's limit" if speed is None else f"{100 * speed:g} cm/s"
    print(
        f"{label} at {name}: more than 10 deg {int((turned > 10).sum())}/{len(turned)}, "
        f"more than 20 deg {int((turned > 20).sum())}, mean {turned.mean():.1f} deg"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grasps", type=int, default=16)
    args = parser.parse_args()
    for speed in LIFT_SPEEDS:
        report("lift", speed, np.array([turns(k, speed, 0.0)[0] for k in range(args.grasps)]))
    for speed in CARRY_SPEEDS:
        carried = [turns(k, SAFE_LIFT_MPS, speed)[1] for k in range(args.grasps)]
        report("carry", speed, np.array(carried))


if __name__ == "__main__":
    main()
