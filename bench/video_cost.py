"""What `eval --video` costs per trial: wall seconds of a trial with and without filming.

    .venv/bin/python bench/video_cost.py                 # pyramid, agents, 2 trials
    .venv/bin/python bench/video_cost.py --trials 1 --method classical

Each trial runs as a job in this process (``jobs.execute``), first plain and then filmed,
and the two result lines must be identical. Filming renders a 320x240 overview frame every
1/8 simulated second with TinyRenderer and encodes them with the ffmpeg of imageio-ffmpeg
(H.264). On a shared machine, run it when idle.
"""

from __future__ import annotations

import argparse
import time

from rich.console import Console
from rich.table import Table

from actionreasoning.eval.jobs import TrialJob, TrialOutput, execute
from actionreasoning.eval.rules import Method
from actionreasoning.eval.trial import TrialSpec
from actionreasoning.eval.trial_config import TrialConfig
from actionreasoning.eval.video import FPS
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


def timed(job: TrialJob) -> tuple[float, TrialOutput]:
    """Wall seconds of one job and what it produced."""
    started = time.perf_counter()
    output = execute(job)
    return time.perf_counter() - started, output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pattern", default="pyramid")
    parser.add_argument("--method", type=Method, default=Method.AGENTS)
    parser.add_argument("--trials", type=int, default=2)
    args = parser.parse_args()
    goal = load_pattern(args.pattern, SceneSpec())
    llm = None if args.method is Method.CLASSICAL else LLMConfig()
    table = Table(title=f"--video cost: {args.method} on {args.pattern}, {FPS} frames per sim s")
    for column in ("trial", "plain s", "filmed s", "cost", "frames", "MP4 KiB"):
        table.add_column(column, justify="right")
    for trial in range(args.trials):
        spec = TrialSpec(
            method=args.method,
            pattern_name=args.pattern,
            goal=goal,
            run_seed=0,
            trial=trial,
            config=TrialConfig(llm=llm),
        )
        plain_s, plain = timed(TrialJob(spec=spec))
        filmed_s, filmed = timed(TrialJob(spec=spec, video=True))
        if plain.result != filmed.result:
            raise SystemExit(f"trial {trial}: filming changed the result")
        frames = 1 + filmed.result.sim_steps // round(1.0 / FPS / spec.config.physics.time_step_s)
        table.add_row(
            str(trial),
            f"{plain_s:.1f}",
            f"{filmed_s:.1f}",
            f"{(filmed_s - plain_s) / plain_s:+.0%}",
            str(frames),
            f"{len(filmed.video) / 1024:.0f}",
        )
    Console().print(table)


if __name__ == "__main__":
    main()
