"""Per physics profile: how a held brick slips and rolls in the hand, and what a trial costs.

    .venv/bin/python bench/profiles.py                  # paper and precise, 24 seeds
    .venv/bin/python bench/profiles.py --seeds 8 --trials 1
    .venv/bin/python bench/profiles.py --physics my_physics.yaml

For each profile and seed, brick 0 of a pyramid trial (run seed 1, trial k) is grasped top-down
at its centre, lifted straight up to 0.30 m, carried in joint space to above the build area
(0.45, 0.30, 0.30) and held there at rest for ``REST_S``. Two ways of moving are compared:
``full speed`` (the controller's speed limits, as the classical script moves) and ``agents``
(the built-in reasoner's choices: lift at 2 cm/s, carry at 10 cm/s). Measured in the tool
frame, from just after the grasp: the roll of the brick in the hand after the lift and after
the carry (mean, max, and how many seeds rolled more than 10 deg), its slide in the hand
after the carry (mm), and the drift in the hand during the rest (mm, deg). Then one trial per
method on the pyramid gives the wall time per trial (one process, this machine).
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

from actionreasoning.control.waypoint import GripperCommand, Waypoint
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial, trial_world
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.models import Pose
from actionreasoning.world.motion import CARRY_SPEED_MPS
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PhysicsProfile
from actionreasoning.world.scenarios import PHYSICS, load_physics
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import SAFE_LIFT_MPS

LIFT_Z = 0.30
OVER_BUILD = (0.45, 0.30, LIFT_Z)
REST_S = 5.0
ROLLED_DEG = 10.0
RUN_SEED = 1


@dataclass(frozen=True)
class Speeds:
    """How long a lift and a carry take (None: the controller's speed limits)."""

    name: str
    lift_s: Callable[[float], float | None]
    carry_s: Callable[[float], float | None]


FULL = Speeds("full speed", lambda _: None, lambda _: None)
AGENTS = Speeds("agents", lambda m: m / SAFE_LIFT_MPS, lambda m: m / CARRY_SPEED_MPS)


def in_hand(scene: Scene) -> tuple[np.ndarray, Rotation]:
    """Brick 0's position (m) and rotation in the tool frame."""
    tcp_p, tcp_q = scene.tcp_pose()
    brick_p, brick_q = scene.brick_pose(0)
    inv = Rotation.from_quat(tcp_q).inv()
    return inv.apply(np.subtract(brick_p, tcp_p)), inv * Rotation.from_quat(brick_q)


def change(
    before: tuple[np.ndarray, Rotation], after: tuple[np.ndarray, Rotation]
) -> tuple[float, float]:
    """Translation (mm) and rotation (deg) between two in-hand poses."""
    mm = float(np.linalg.norm(after[0] - before[0]) * 1000.0)
    return mm, float(np.degrees((before[1].inv() * after[1]).magnitude()))


def hold_and_carry(physics: PhysicsProfile, trial: int, speeds: Speeds) -> tuple[float, ...]:
    """Roll after lift, roll and slide after carry, slide and roll during the rest."""
    goal = load_pattern("pyramid", SceneSpec())
    spec = TrialSpec(Method.AGENTS, "pyramid", goal, RUN_SEED, trial, TrialConfig(physics=physics))
    with trial_world(spec) as world:
        scene, controller = world.scene, world.controller
        position, quat = scene.brick_pose(0)
        tool = top_down_quat(quat_yaw(quat))

        def move(xyz, path="joint", seconds=None, **kw) -> None:
            ticks = None if seconds is None else scene.ticks_for(seconds)
            pose = Pose(position_m=tuple(xyz), quat_xyzw=tool)
            controller.execute(Waypoint(pose=pose, path=path, min_ticks=ticks, **kw))

        x, y, z = position
        move((x, y, 0.15), gripper=GripperCommand.OPEN, gripper_opening_m=0.135)
        move((x, y, z), path="linear")
        controller.grip(GripperCommand.CLOSE)
        grasped = in_hand(scene)
        move((x, y, LIFT_Z), path="linear", seconds=speeds.lift_s(LIFT_Z - z))
        lifted = in_hand(scene)
        move(OVER_BUILD, seconds=speeds.carry_s(math.dist((x, y, LIFT_Z), OVER_BUILD)))
        carried = in_hand(scene)
        scene.step(scene.ticks_for(REST_S))
        rested = in_hand(scene)
    return (
        change(grasped, lifted)[1],
        change(grasped, carried)[1],
        change(grasped, carried)[0],
        *change(carried, rested),
    )


def wall_time(physics: PhysicsProfile, method: Method, trials: int) -> float:
    """Mean wall time (s) of a pyramid trial of ``method``."""
    goal = load_pattern("pyramid", SceneSpec())
    start = time.perf_counter()
    for trial in range(trials):
        run_trial(TrialSpec(method, "pyramid", goal, RUN_SEED, trial, TrialConfig(physics=physics)))
    return (time.perf_counter() - start) / trials


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seeds", type=int, default=24, help="grasps per profile and speed")
    parser.add_argument("--trials", type=int, default=2, help="trials per method for wall time")
    parser.add_argument("--physics", nargs="*", default=list(PHYSICS), help="profiles or files")
    args = parser.parse_args()
    console = Console()
    slip = Table(title=f"a held brick in the hand ({args.seeds} grasps each)")
    for column in (
        "profile",
        "moves",
        "rotation after lift deg mean/max",
        f"lifts turned >{ROLLED_DEG:g} deg",
        "rotation after carry deg mean/max",
        f"carries turned >{ROLLED_DEG:g} deg",
        "slide after carry mm mean/max",
        f"drift at rest ({REST_S:g} s) mm / deg, max",
    ):
        slip.add_column(column)
    cost = Table(title=f"wall time per pyramid trial ({args.trials} trials each, one process)")
    for column in ("profile", *(m.value for m in Method)):
        cost.add_column(column)
    for name in args.physics:
        physics = load_physics(name)
        for speeds in (FULL, AGENTS):
            rows = np.array([hold_and_carry(physics, k, speeds) for k in range(args.seeds)])
            lift, carry, slide, rest_mm, rest_deg = rows.T
            slip.add_row(
                physics.name,
                speeds.name,
                f"{lift.mean():.1f} / {lift.max():.1f}",
                f"{int((lift > ROLLED_DEG).sum())}/{args.seeds}",
                f"{carry.mean():.1f} / {carry.max():.1f}",
                f"{int((carry > ROLLED_DEG).sum())}/{args.seeds}",
                f"{slide.mean():.1f} / {slide.max():.1f}",
                f"{rest_mm.max():.2f} / {rest_deg.max():.2f}",
            )
        cost.add_row(physics.name, *(f"{wall_time(physics, m, args.trials):.1f} s" for m in Method))
    console.print(slip)
    console.print(cost)


if __name__ == "__main__":
    main()
