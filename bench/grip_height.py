"""How far a held brick rolls in the hand by how high it is gripped (paper physics): on the
lift, and on the carry after it.

    .venv/bin/python bench/grip_height.py --grasps 16

Brick 0 of pyramid trials (run seed 1, trial k) is grasped top-down at its centre raised
or lowered by each offset (mm; negative: below the centre), lifted straight up to 0.30 m at
the safe lift speed, and carried over the build area in a joint move at the carry speed
(the agents' duration formula: the straight distance over ``CARRY_SPEED_MPS``). Counts the
grasps whose brick turned more than 10 and 20 deg in the hand on the lift, and on the lift
and carry together.
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
from actionreasoning.world.motion import CARRY_SPEED_MPS
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import SAFE_LIFT_MPS

OFFSETS_MM = (-6.0, -3.0, 0.0, 3.0, 6.0)
OPENING_M = 0.135


def turns(trial: int, offset_mm: float) -> tuple[float, float]:
    """Turn of brick 0 in the hand (deg) after the lift, and after the lift and carry."""
    goal = load_pattern("pyramid", SceneSpec())
    spec = TrialSpec(Method.AGENTS, "pyramid", goal, RUN_SEED, trial, TrialConfig())
    with trial_world(spec) as world:
        scene, controller = world.scene, world.controller
        (x, y, z), quat = scene.brick_pose(0)
        tool = top_down_quat(quat_yaw(quat))

        def to(xyz: tuple[float, float, float], mps: float | None = None, **kw: object) -> None:
            """A move to ``xyz`` at mean speed ``mps`` (None: the controller's limits)."""
            here = scene.tcp_pose()[0]
            ticks = None if mps is None else scene.ticks_for(math.dist(here, xyz) / mps)
            pose = Pose(position_m=xyz, quat_xyzw=tool)
            controller.execute(Waypoint(pose=pose, min_ticks=ticks, **kw))  # type: ignore[arg-type]

        to((x, y, 0.15), gripper=GripperCommand.OPEN, gripper_opening_m=OPENING_M)
        to((x, y, z + offset_mm / 1000.0), path="linear")
        controller.grip(GripperCommand.CLOSE)
        grasped = in_hand(scene)
        to((x, y, LIFT_Z), SAFE_LIFT_MPS, path="linear")
        lifted = change(grasped, in_hand(scene))[1]
        to(OVER_BUILD, CARRY_SPEED_MPS)
        return lifted, change(grasped, in_hand(scene))[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grasps", type=int, default=16)
    args = parser.parse_args()
    for offset in OFFSETS_MM:
        lifted, carried = np.array([turns(k, offset) for k in range(args.grasps)]).T
        print(
            f"gripped {offset:+g} mm: lift rolled >10 deg {int((lifted > 10).sum())}, "
            f">20 deg {int((lifted > 20).sum())}; lift and carry >10 deg "
            f"{int((carried > 10).sum())}, >20 deg {int((carried > 20).sum())} of {len(lifted)}; "
            f"mean {carried.mean():.1f} deg, largest {carried.max():.1f} deg"
        )


if __name__ == "__main__":
    main()
