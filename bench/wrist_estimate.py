"""Measure how well the knowledge base's wrist estimate matches the arm's inverse kinematics.

    python bench/wrist_estimate.py [SAMPLES]

Draws SAMPLES (default 300) top-down tool poses from a fixed seed (radius 0.35-0.8 m,
azimuth within 162 deg of the x axis, height 0.03-0.45 m, any yaw), solves each with the
arm's IK and prints, over the poses it reaches, the error of ``formulas.wrist_deg``
against joint 7: mean, standard deviation and largest (deg). The prompts state the
estimate to 5 deg; ``tests/test_formulas.py`` checks that bound on 120 poses.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.tools.formulas import wrist_deg
from actionreasoning.world.geometry import top_down_quat


def main(samples: int) -> None:
    arm, rng, errors = KinematicArm(), np.random.default_rng(0), []
    for _ in range(samples):
        radius, heading = rng.uniform(0.35, 0.8), rng.uniform(-0.9 * math.pi, 0.9 * math.pi)
        position = (radius * math.cos(heading), radius * math.sin(heading), rng.uniform(0.03, 0.45))
        yaw = rng.uniform(-180.0, 180.0)
        solution = arm.solve(position, top_down_quat(math.radians(yaw)))
        if solution.reached:
            error = wrist_deg(position, yaw) - math.degrees(solution.joints_rad[6])
            errors.append((error + 180.0) % 360.0 - 180.0)
    found = np.abs(errors)
    print(
        f"{len(errors)} of {samples} poses reached; wrist estimate error (deg): mean "
        f"{np.mean(errors):+.2f}, std {np.std(errors):.2f}, largest {found.max():.2f}"
    )


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 300)
