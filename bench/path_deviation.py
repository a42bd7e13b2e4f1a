"""How far the tool strays from the path it was sent along: what c_min must cover.

    .venv/bin/python bench/path_deviation.py --trials 2

Runs agents trials (built-in reasoner, pyramid, paper physics, no noise) and, every
simulation step, records where the commanded joint targets put the tool centre point
(forward kinematics on a kinematic copy of the arm: the planned path) and where it is. The
deviation is the distance from the tool to the nearest point of the path planned over the
last LAG_S seconds: the tool lags behind its targets along the path (centimetres in a fast
joint move), which a clearance check along the plan covers, but it also strays off the
path, which it does not. Prints the largest deviation and the 99th percentile per trial.
"""

from __future__ import annotations

import argparse
import math
from collections import deque

import numpy as np

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialSpec, run_trial
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec

#: How far back the planned path is searched for the point nearest the tool.
LAG_S = 2.0


class Deviation(TrialObserver):
    """Distance of the tool from its recently planned path, every step."""

    every_s = 1.0 / 240.0

    def __init__(self) -> None:
        self.arm = KinematicArm()
        self.planned: deque[tuple[float, ...]] = deque(maxlen=int(LAG_S / self.every_s))
        self.distances: list[float] = []

    def tick(self, scene: Scene) -> None:
        self.planned.append(self.arm.forward(scene.arm_targets)[0])
        actual, _ = scene.tcp_pose()
        self.distances.append(min(math.dist(p, actual) for p in self.planned))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    goal = load_pattern("pyramid", SceneSpec())
    worst = 0.0
    for trial in range(args.trials):
        observer = Deviation()
        spec = TrialSpec(Method.AGENTS, "pyramid", goal, args.seed, trial, TrialConfig())
        run_trial(spec, [observer])
        d = np.asarray(observer.distances)
        worst = max(worst, float(d.max()))
        print(
            f"trial {trial}: {len(d)} steps, largest {1000 * d.max():.1f} mm, "
            f"99th percentile {1000 * np.percentile(d, 99):.1f} mm"
        )
    print(f"largest over {args.trials} trials: {1000 * worst:.1f} mm")


if __name__ == "__main__":
    main()
