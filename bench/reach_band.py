"""Measure where top-down grasps are reachable: radius x height, over azimuths and yaws.

    python bench/reach_band.py

Prints, per radius and tool height, the share of (azimuth, grasp yaw) pairs for which the
rest-pose IK solver reaches 0.1 mm / 0.05 deg with the gripper at that yaw or turned by
180 deg (a parallel gripper grasps the same either way; joint 7 stops short of +-180 deg,
so one of the two is always out). The ReachBand defaults in world/scene_spec.py are the
band where every pair was reached.
"""

from __future__ import annotations

import math

import numpy as np

from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.world.geometry import top_down_quat

RADII_M = (0.38, 0.40, 0.41, 0.42, 0.44, 0.50, 0.60, 0.70, 0.72, 0.74, 0.75, 0.76, 0.78)
HEIGHTS_M = (0.03, 0.09, 0.15, 0.30, 0.45)
AZIMUTHS_DEG = np.arange(-165.0, 166.0, 15.0)
YAWS_DEG = np.arange(-90.0, 90.0, 15.0)


def main() -> None:
    arm = KinematicArm()
    print("radius_m " + " ".join(f"z={z:.2f}".rjust(8) for z in HEIGHTS_M))
    for radius in RADII_M:
        cells = []
        for z in HEIGHTS_M:
            reached = 0
            for azimuth in np.radians(AZIMUTHS_DEG):
                for yaw in np.radians(YAWS_DEG):
                    position = (radius * math.cos(azimuth), radius * math.sin(azimuth), z)
                    reached += any(
                        arm.solve(position, top_down_quat(azimuth + yaw + flip)).reached
                        for flip in (0.0, math.pi)
                    )
            share = reached / (len(AZIMUTHS_DEG) * len(YAWS_DEG))
            cells.append(f"{share:7.1%}".rjust(8))
        print(f"{radius:8.2f} " + " ".join(cells), flush=True)
    arm.close()


if __name__ == "__main__":
    main()
