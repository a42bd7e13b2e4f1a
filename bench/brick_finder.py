"""How well the image tier's pictures place the bricks: the brick finder's error per brick.

    .venv/bin/python bench/brick_finder.py --layouts 6

Lays out six catalogue bricks per seed (the pick area's sampler, paper physics, settled),
the arm waiting at its ready pose over the pick area as before every pick. The top-down and
the pick-side cameras are rendered, and the bricks are found from their colour and depth
alone (reasoners/brick_finder.py): a camera places a brick only where its footprint, laid
on the top face's outline, explains the picture (covers no ground the picture shows bare)
and the outline pins it (shows a long side and a short end), so a brick the arm half hides
from above is left to the pick-side camera; of two cameras' finds of a brick, the one of
more pixels is kept. Each brick is matched to the nearest one found.
Prints the bricks missed and the spurious finds, and the centre offset (cm) and yaw error
(deg) against the true poses: mean, 95th percentile and largest. The paper's mean
placement errors, 0.637 cm and 0.703 deg, are what a build on these finds must reach.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from actionreasoning.reasoners.brick_finder import SeenBrick, find_bricks, merged
from actionreasoning.sim.eyes import capture
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.world.cameras import PICK_SIDE, TOP_DOWN
from actionreasoning.world.geometry import quat_yaw
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import READY_POSE
from actionreasoning.world.physics import PAPER
from actionreasoning.world.scene_spec import SceneSpec

#: A find this far (m, in the plane) from every brick is spurious.
MATCH_M = 0.05


def seen(scene: Scene, footprint: tuple[float, float]) -> list[SeenBrick]:
    """The bricks the two depth cameras find, one find per brick."""
    shots = [capture(scene.client, camera) for camera in (TOP_DOWN, PICK_SIDE)]
    return merged(
        find
        for shot in shots
        for find in find_bricks(shot.rgb, shot.depth_m, shot.camera, [footprint])
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--layouts", type=int, default=6, help="seeds of six-brick layouts")
    parser.add_argument("--seed", type=int, default=0, help="the first seed")
    args = parser.parse_args()
    spec = SceneSpec()
    footprint = (spec.brick_size_m[0], spec.brick_size_m[1])
    arm = KinematicArm()
    ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
    offsets, yaws, missed, spurious = [], [], 0, 0
    for seed in range(args.seed, args.seed + args.layouts):
        scene = Scene(spec, sample_pick_poses(np.random.default_rng(seed), 6, spec), ready, PAPER)
        try:
            scene.step(scene.ticks_for(1.0))
            found, matched = seen(scene, footprint), set()
            for brick in range(len(scene.bricks)):
                position, quat = scene.brick_pose(brick)
                distances = [math.dist(f.top_centre_m[:2], position[:2]) for f in found]
                if not distances or min(distances) > MATCH_M:
                    missed += 1
                    continue
                nearest = int(np.argmin(distances))
                matched.add(nearest)
                offsets.append(100.0 * distances[nearest])
                turn = (found[nearest].yaw_rad - quat_yaw(quat) + math.pi / 2) % math.pi
                yaws.append(abs(math.degrees(turn - math.pi / 2)))
            spurious += len(found) - len(matched)
        finally:
            scene.close()
    arm.close()
    print(f"bricks found {len(offsets)}, missed {missed}, spurious finds {spurious}")
    for name, values in (("centre offset cm", offsets), ("yaw error deg", yaws)):
        data = np.asarray(values)
        print(
            f"{name}: mean {data.mean():.3f}, p95 {np.percentile(data, 95):.3f}, "
            f"max {data.max():.3f}"
        )


if __name__ == "__main__":
    main()
