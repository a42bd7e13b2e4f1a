"""What `eval --video` costs per trial: wall seconds of a trial with and without filming,
and the CPU seconds of its film process.

    .venv/bin/python bench/video_cost.py                 # pyramid, agents, 2 trials
    .venv/bin/python bench/video_cost.py --trials 1 --method classical

Each trial runs as a job in this process (``jobs.execute``), first plain and then filmed,
and the two result lines must be identical. The trial only reads the scene's pose every
1/FPS simulated second; its film process (with the ffmpeg of imageio-ffmpeg under it)
renders the 320x240 overview frames with TinyRenderer and encodes them (H.264), on another
core. The wall cost is what a trial takes longer where a core is free; the film's CPU is
what filming takes from a machine whose cores all run trials (``--workers`` = cores). On a
shared machine, run it when idle.
"""

from __future__ import annotations

import argparse
import resource
import time

from rich.console import Console
from rich.table import Table

from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.recording.video import FPS
from actionreasoning.runs.jobs import TrialJob, TrialOutput, execute
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


def timed(job: TrialJob) -> tuple[float, float, TrialOutput]:
    """Wall seconds of one job, CPU seconds of its child processes, and what it produced."""
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    output = execute(job)
    wall_s = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu_s = after.ru_utime + after.ru_stime - children.ru_utime - children.ru_stime
    return wall_s, cpu_s, output


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pattern", default="pyramid")
    parser.add_argument("--method", type=Method, default=Method.AGENTS)
    parser.add_argument("--trials", type=int, default=2)
    args = parser.parse_args()
    goal = load_pattern(args.pattern, SceneSpec())
    llm = None if args.method is Method.CLASSICAL else LLMConfig()
    table = Table(title=f"--video cost: {args.method} on {args.pattern}, {FPS} frames per sim s")
    columns = ("trial", "plain s", "filmed s", "wall cost", "film CPU s", "CPU cost", "frames")
    for column in (*columns, "MP4 KiB"):
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
        plain_s, _, plain = timed(TrialJob(spec=spec))
        filmed_s, film_cpu_s, filmed = timed(TrialJob(spec=spec, video=True))
        if plain.result != filmed.result:
            raise SystemExit(f"trial {trial}: filming changed the result")
        frames = 1 + filmed.result.sim_steps // round(1.0 / FPS / spec.config.physics.time_step_s)
        table.add_row(
            str(trial),
            f"{plain_s:.1f}",
            f"{filmed_s:.1f}",
            f"{(filmed_s - plain_s) / plain_s:+.0%}",
            f"{film_cpu_s:.1f}",
            f"{film_cpu_s / plain_s:+.0%}",
            str(frames),
            f"{len(filmed.video) / 1024:.0f}",
        )
    Console().print(table)


if __name__ == "__main__":
    main()
