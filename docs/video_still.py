"""Take one frame of a trial's video (``eval --video``) as a PNG, enlarged for reading.

Makes ``docs/video_still.png``, from the repository's root::

    actionreasoning eval --method agents --pattern pyramid --trials 2 --seed 0 --video \
        --out runs/film
    python docs/video_still.py runs/film/videos/trial_001_ok.mp4 --time 34.4 \
        --out docs/video_still.png

A video has a frame at the start and one every 1/FPS simulated seconds (``recording/video.py``),
so the frame shown at ``--time`` seconds is number ``round(time * FPS)``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import imageio.v3 as iio
from PIL import Image

from actionreasoning.recording.video import FPS


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("video", type=Path, help="an MP4 written by eval --video")
    parser.add_argument("--time", type=float, required=True, help="simulated seconds")
    parser.add_argument("--out", type=Path, default=Path("video_still.png"))
    parser.add_argument("--scale", type=int, default=2, help="enlargement (default 2)")
    args = parser.parse_args()
    index = round(args.time * FPS)
    try:
        frame = iio.imread(args.video, index=index, plugin="FFMPEG")
    except IndexError:
        raise SystemExit(f"{args.video} has no frame at {args.time} s (frame {index})") from None
    picture = Image.fromarray(frame)
    picture = picture.resize(
        (picture.width * args.scale, picture.height * args.scale), Image.LANCZOS
    )
    picture.save(args.out, optimize=True)
    print(f"{args.out}: frame {index} ({args.time} s) of {args.video}")


if __name__ == "__main__":
    main()
