"""What a closing grip corrects: a grasp off across the brick's width, along it, or turned.

    .venv/bin/python bench/grip_centring.py --trials 2

Under paper physics, for the first brick of pyramid trials, moves the open gripper (0.135 m)
straight down to the brick's centre shifted across its width (5, 10, 15 mm), along its
length (3 mm) or turned (3, 6, 10 deg), closes, and prints what sigma_3 would measure: the
tool-to-brick offset and yaw once the pads hold the brick, and how far the brick slid. The
coupled pads centre a brick across its width (the offset left is below 0.5 mm), but keep an
offset along its length and most of a yaw: what the pre-move forecast of sigma_3 allows
(``agents/plans.py``, ``pad_room_m`` in world/tolerances.py).
"""

from __future__ import annotations

import argparse
import math

from scipy.spatial.transform import Rotation

from actionreasoning.agents.outputs import WaypointProposal
from actionreasoning.tools import formulas
from actionreasoning.tools.contact import FINGER_CONTACTS, SLIP
from actionreasoning.tools.geometry import BrickQuery
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.geometry import quat_yaw, top_down_quat, wrap_angle
from actionreasoning.world.models import Progress
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.stages import Stage

#: (across the width m, along the length m, yaw deg) of each grasp tried.
GRASPS = [
    (0.0, 0.0, 0.0),
    (0.005, 0.0, 0.0),
    (0.010, 0.0, 0.0),
    (0.015, 0.0, 0.0),
    (0.0, 0.003, 0.0),
    (0.0, 0.0, 3.0),
    (0.0, 0.0, 6.0),
    (0.0, 0.0, 10.0),
]
OPENING_M = 0.135
ABOVE_M = 0.15


def grasp(trial: int, seed: int, across_m: float, along_m: float, yaw_deg: float) -> str:
    """One grasp of trial ``trial``'s first brick, and what sigma_3 measures of it."""
    config = TrialConfig()
    goal = load_pattern("pyramid", config.scene)
    spec = TrialSpec(Method.AGENTS, "pyramid", goal, seed, trial, config)
    with trial_world(spec) as world:
        sim = SimWorld(world.controller, goal, world.sensor)
        brick = sim.observe(Progress(step=Stage.PRE_GRASP)).bricks[0]
        yaw = quat_yaw(brick.pose.quat_xyzw)
        quat = top_down_quat(yaw + math.radians(yaw_deg))
        x, y, z = formulas.grasp_pose(brick.pose, brick.size_m, quat).position_m
        c, s = math.cos(yaw), math.sin(yaw)
        x, y = x + along_m * c - across_m * s, y + along_m * s + across_m * c
        sim.move(WaypointProposal(position_m=(x, y, z + ABOVE_M), quat_xyzw=quat))
        sim.grip(OPENING_M)
        sim.move(WaypointProposal(position_m=(x, y, z), quat_xyzw=quat, path="linear"))
        sim.grip(None)
        after = sim.observe(Progress(current_brick=brick.id, step=Stage.GRASP))
        tools = sim.tools(after)
        slip = SLIP(tools, BrickQuery(brick_id=brick.id))
        pads = FINGER_CONTACTS(tools, BrickQuery(brick_id=brick.id))
        offset = Rotation.from_quat(after.robot.ee_pose.quat_xyzw).apply(slip.offset_in_gripper_m)
        held = after.brick(brick.id).pose
        turn = wrap_angle(2 * (quat_yaw(held.quat_xyzw) - quat_yaw(after.robot.ee_pose.quat_xyzw)))
        slid = math.dist(held.position_m[:2], brick.pose.position_m[:2])
        return (
            f"trial {trial}: across {across_m * 1000:+4.0f} mm, along {along_m * 1000:+2.0f} mm, "
            f"yaw {yaw_deg:+5.1f} deg -> offset {math.hypot(*offset) * 1000:.2f} mm, yaw "
            f"{math.degrees(turn) / 2:+.2f} deg, pads {pads.normal_n[0]:.0f}/"
            f"{pads.normal_n[1]:.0f} N, brick slid {slid * 1000:.1f} mm"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=2, help="trials (a brick each)")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for trial in range(args.trials):
        for across, along, yaw in GRASPS:
            print(grasp(trial, args.seed, across, along, yaw), flush=True)


if __name__ == "__main__":
    main()
