"""Load an `actionreasoning export lerobot` dataset with LeRobot's own dataset class, and show
what a policy would be trained on: its episodes (which trials succeeded), its frames, its
features, and the shapes of one frame.

LeRobot cannot share a virtual environment with actionreasoning (its releases pin an older
Rerun SDK), so run this in an environment of its own (docs/lerobot.md):

    python3.11 -m venv lerobot-venv && lerobot-venv/bin/pip install lerobot==0.4.4
    lerobot-venv/bin/python examples/lerobot_load.py runs/dataset

It needs only LeRobot, and reads nothing but DIR (no network).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lerobot.datasets.lerobot_dataset import LeRobotDataset


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset", type=Path, help="the directory `export lerobot --out` wrote")
    parser.add_argument("--frame", type=int, default=0, help="the frame whose shapes to show")
    parser.add_argument(
        "--video-backend",
        default="pyav",
        help="LeRobot's video decoder: pyav (its wheel brings FFmpeg) or torchcodec (needs "
        "the system's FFmpeg libraries, 4 to 8)",
    )
    args = parser.parse_args()

    dataset = LeRobotDataset(
        repo_id=f"local/{args.dataset.name}", root=args.dataset, video_backend=args.video_backend
    )
    meta = dataset.meta
    print(f"{meta.info['codebase_version']} dataset of a {meta.robot_type} at {dataset.fps} fps")
    print(f"episodes: {dataset.num_episodes}, frames: {dataset.num_frames}")
    for episode in meta.episodes:
        outcome = "success" if episode["success"] else f"failure ({episode['failure']})"
        print(
            f"  episode {episode['episode_index']}: trial {episode['trial']}, "
            f"{episode['length']} frames, {outcome}: {episode['tasks'][0]}"
        )
    print("features:")
    for name, feature in dataset.features.items():
        print(f"  {name}: {feature['dtype']} {tuple(feature['shape'])}")
    item = dataset[args.frame]
    print(f"frame {args.frame} (episode {int(item['episode_index'])}, task {item['task']!r}):")
    for name, value in item.items():
        if hasattr(value, "shape"):
            print(f"  {name}: {tuple(value.shape)} {value.dtype}")
    state = ", ".join(f"{v:.3f}" for v in item["observation.state"].tolist())
    print(f"  observation.state = [{state}]")


if __name__ == "__main__":
    main()
