"""Measure whether a held brick slips in the gripper, per physics setting.

    .venv/bin/python bench/grip_slip.py            # 10 settings, 3 seeds each
    .venv/bin/python bench/grip_slip.py --quick    # 110 N, 150 iterations (4 settings), 1 seed
    .venv/bin/python bench/grip_slip.py --sweep-s 1.0   # faster sweeps (harder on the grip)

Settings, each the ``precise`` profile with some fields replaced (``PRECISE.model_copy``):
time step {1/240, 1/480} s x solver iterations {50, 150} x finger friction anchor {off, on}, all
at 110 N per finger (8 settings); plus, at the defaults (1/480 s, 150 iterations, anchor on),
grip force 60 N and 150 N (2 settings). Each seed spawns one 0.20 x 0.095 x 0.06 m, 1.5 kg
brick, settles it for ``SPAWN_SETTLE_S``, picks it as ``classical.py`` does (approach above in
2.0 s, linear descent to the centre in 1.0 s, CLOSE, linear lift to 0.30 m in 1.0 s), then
sweeps in joint space to above the build area (0.44, 0.37, 0.30) and back, each sweep
``--sweep-s`` long (default 2.0 s, the classical transfer time). All durations are in seconds,
converted to steps with ``Scene.ticks_for``. Slip is the change of the brick's pose in the
tool-centre-point frame from just after closing: at the end (mean/max over seeds) and its peak,
sampled every ~10 ms of simulated time (``ticks_for(0.01)``: 2 steps at 1/240 s, 5 at 1/480 s)
during lift and sweeps. Also printed: the peak TCP speed, the smallest per-finger normal force
seen (Scene.finger_contacts), how many samples had a finger below 1 N, and how many bricks
dropped (z < 0.1 m at the end).
"""

from __future__ import annotations

import argparse
import itertools
import math
import time
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.spatial.transform import Rotation

from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.errors import UnreachableError
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import SPAWN_SETTLE_S
from actionreasoning.world.geometry import quat_yaw, top_down_quat
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import READY_POSE, Pose
from actionreasoning.world.physics import PRECISE, PhysicsProfile
from actionreasoning.world.scene_spec import SceneSpec

TIME_STEPS = (240, 480)  # steps per second: dt = 1/240 s, 1/480 s
ITERATIONS = (50, 150)
ANCHORS = (False, True)
BASE_FORCE_N = 110.0
EXTRA_FORCES_N = (60.0, 150.0)  # at the precise profile otherwise
QUICK_ITERATIONS = 150
COLUMNS = (
    "dt",
    "iters",
    "anchor",
    "force N",
    "slip mm mean/max",
    "slip deg mean/max",
    "peak mm",
    "peak deg",
    "peak TCP m/s",
    "min finger N",
    "contact lost",
    "dropped",
)
FAR_XY = (0.44, 0.37)
LIFT_Z, APPROACH_M = 0.30, 0.12
APPROACH_S, DESCENT_S, LIFT_S, SWEEP_S, SAMPLE_S = 2.0, 1.0, 1.0, 2.0, 0.01


@dataclass
class Probe:
    """Brick pose in the TCP frame right after closing, and the worst seen since."""

    scene: Scene
    ref: tuple[np.ndarray, Rotation] = field(init=False)
    peak: list[float] = field(default_factory=lambda: [0.0, 0.0, 0.0])  # mm, deg, TCP m/s
    min_force_n: float = math.inf
    lost: int = 0  # samples with a finger below 1 N

    def __post_init__(self) -> None:
        self.ref = self.relative()

    def relative(self) -> tuple[np.ndarray, Rotation]:
        tcp_p, tcp_q = self.scene.tcp_pose()
        brick_p, brick_q = self.scene.brick_pose(0)
        inv = Rotation.from_quat(tcp_q).inv()
        return inv.apply(np.subtract(brick_p, tcp_p)), inv * Rotation.from_quat(brick_q)

    def slip(self) -> tuple[float, float]:
        """Translation (mm) and rotation (deg) of the brick in the TCP frame since the grasp."""
        pos, rot = self.relative()
        mm = float(np.linalg.norm(pos - self.ref[0]) * 1000.0)
        return mm, float(np.degrees((self.ref[1].inv() * rot).magnitude()))

    def sample(self) -> None:
        speed = float(np.linalg.norm(self.scene.tcp_velocity()[0]))
        self.peak = [max(a, b) for a, b in zip(self.peak, (*self.slip(), speed), strict=True)]
        force = min(c.normal_n for c in self.scene.finger_contacts(0))
        self.min_force_n, self.lost = min(self.min_force_n, force), self.lost + (force < 1.0)


class ProbedScene(Scene):
    """A scene that calls its probe (once set) every ``SAMPLE_S`` of simulated time."""

    probe: Probe | None = None

    def step(self, ticks: int = 1) -> None:
        every = self.ticks_for(SAMPLE_S)
        for _ in range(ticks):
            super().step(1)
            if self.probe is not None and self.ticks % every == 0:
                self.probe.sample()


def run_once(arm: KinematicArm, physics: PhysicsProfile, seed: int, sweep_s: float) -> list[float]:
    """End mm, end deg, peak mm, peak deg, peak TCP m/s, min finger N, lost, dropped."""
    spec = SceneSpec()
    poses = sample_pick_poses(np.random.default_rng(seed), 1, spec)
    ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
    scene = ProbedScene(spec, poses, ready, physics)
    try:
        scene.step(scene.ticks_for(SPAWN_SETTLE_S))
        run = partial(WaypointController(scene, arm).execute, settle=False)  # as classical.py
        (px, py, pz), quat = scene.brick_pose(0)
        far = (*FAR_XY, LIFT_Z)

        def wrist(yaw: float) -> float:  # like classical.py, at transfer height, both ends
            return max(abs(arm.solve(xy, top_down_quat(yaw)).joints_rad[6])
                       for xy in ((px, py, LIFT_Z), far))  # fmt: skip

        yaw = min((quat_yaw(quat) + flip for flip in (0.0, math.pi)), key=wrist)

        def at(x: float, y: float, z: float) -> Pose:
            return Pose(position_m=(x, y, z), quat_xyzw=top_down_quat(yaw))

        ticks = scene.ticks_for
        above = at(px, py, pz + APPROACH_M)
        run(Waypoint(pose=above, gripper=GripperCommand.OPEN, ticks=ticks(APPROACH_S)))
        run(Waypoint(pose=at(px, py, pz), path="linear", ticks=ticks(DESCENT_S)))
        run(Waypoint(pose=at(px, py, pz), gripper=GripperCommand.CLOSE, ticks=1))
        scene.probe = probe = Probe(scene)
        run(Waypoint(pose=at(px, py, LIFT_Z), path="linear", ticks=ticks(LIFT_S)))
        run(Waypoint(pose=at(*far), ticks=ticks(sweep_s)))
        run(Waypoint(pose=at(px, py, LIFT_Z), ticks=ticks(sweep_s)))
        probe.sample()
        dropped = float(scene.brick_pose(0)[0][2] < 0.1)
        return [*probe.slip(), *probe.peak, probe.min_force_n, probe.lost, dropped]
    finally:
        scene.close()


def settings(quick: bool) -> list[tuple[int, int, bool, float]]:
    """(steps per second, solver iterations, friction anchor, grip force N) per table row."""
    grid = [(rate, iterations, anchor, BASE_FORCE_N)
            for rate, iterations, anchor in itertools.product(TIME_STEPS, ITERATIONS, ANCHORS)
            if not quick or iterations == QUICK_ITERATIONS]  # fmt: skip
    if quick:
        return grid
    base = PRECISE
    rate, iterations = round(1.0 / base.time_step_s), base.solver_iterations
    extra = [(rate, iterations, base.friction_anchors, f) for f in EXTRA_FORCES_N]
    return grid + extra


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="110 N, 150 iterations only, one seed per setting"
    )
    parser.add_argument("--sweep-s", type=float, default=SWEEP_S, help="seconds per sweep")
    args = parser.parse_args()
    seeds = range(1 if args.quick else 3)
    table = Table(title=f"Grip slip, sweep {args.sweep_s:g} s each way, "
                  f"{len(seeds)} seed(s) per setting")  # fmt: skip
    for col in COLUMNS:
        table.add_column(col, justify="right")
    arm, start = KinematicArm(), time.perf_counter()
    for rate, iterations, anchor, force in settings(args.quick):
        physics = PRECISE.model_copy(update={
            "time_step_s": 1.0 / rate, "solver_iterations": iterations,
            "friction_anchors": anchor, "grip_force_n": force,
        })  # fmt: skip
        setting = (f"1/{rate}", str(iterations), "on" if anchor else "off", f"{force:.0f}")
        try:
            r = np.array([run_once(arm, physics, seed, args.sweep_s) for seed in seeds])
        except UnreachableError as error:
            table.add_row(*setting, f"unreachable: {error}")
            continue
        table.add_row(
            *setting,
            *(f"{r[:, i].mean():.2f} / {r[:, i].max():.2f}" for i in (0, 1)),
            *(f"{r[:, i].max():.2f}" for i in (2, 3, 4)),
            f"{r[:, 5].min():.1f}", f"{r[:, 6].sum():.0f}", f"{r[:, 7].sum():.0f}/{len(seeds)}",
        )  # fmt: skip
    arm.close()
    Console(width=170).print(table)
    print(f"wall time {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
