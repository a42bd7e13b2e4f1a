"""Measure where top-down grasps are reachable: radius x height, over azimuths and yaws.

    python bench/reach_band.py

Prints, per radius and tool height, the share of (azimuth, yaw) pairs whose IK converges to
0.1 mm / 0.05 deg with the rest-pose solver, and the smallest joint-limit margin. The
ReachBand defaults in world/scene_spec.py are the band where every pair converged.
"""

from __future__ import annotations

import math

import numpy as np

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.world.geometry import top_down_quat

RADII_M = (0.38, 0.40, 0.42, 0.44, 0.50, 0.60, 0.70, 0.74, 0.76, 0.78, 0.80)
HEIGHTS_M = (0.03, 0.09, 0.15, 0.30, 0.45)
AZIMUTHS_DEG = np.arange(-165.0, 166.0, 15.0)
YAWS_DEG = np.arange(-180.0, 180.0, 30.0)


def main() -> None:
    arm = KinematicArm()
    print("radius_m " + " ".join(f"z={z:.2f}".rjust(14) for z in HEIGHTS_M))
    for radius in RADII_M:
        cells = []
        for z in HEIGHTS_M:
            reached, margin = 0, math.inf
            for azimuth in np.radians(AZIMUTHS_DEG):
                for yaw in np.radians(YAWS_DEG):
                    position = (radius * math.cos(azimuth), radius * math.sin(azimuth), z)
                    solution = arm.solve(position, top_down_quat(azimuth + yaw))
                    reached += solution.reached
                    margin = min(margin, solution.joint_limit_margin_rad)
            share = reached / (len(AZIMUTHS_DEG) * len(YAWS_DEG))
            cells.append(f"{share:6.1%} m{margin:5.2f}".rjust(14))
        print(f"{radius:8.2f} " + " ".join(cells))
    arm.close()


if __name__ == "__main__":
    main()
