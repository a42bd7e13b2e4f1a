"""How fast evaluation runs: simulation steps per second, seconds per trial per method, and
the speed-up of `eval --workers 2` over one worker.

    .venv/bin/python bench/throughput.py          # pyramid, 2 trials per method, 4 for speed-up
    .venv/bin/python bench/throughput.py --trials 1 --speedup-trials 2   # quicker, rougher

Steps/s: ``Scene.step`` of the pyramid trial's scene (arm at rest, six bricks) for
``--steps`` steps, best of three. Seconds per trial: ``run_trial`` of trials 0..N-1 of each
method, one after another in this process (its mean and the sim steps per trial). Speed-up:
``run_eval`` of the classical method on ``--speedup-trials`` trials, serial and then with two
workers, each into a fresh directory; the two results.jsonl must hold the same lines. Wall
times include process start-up of the workers. On a shared machine, run it when idle.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.table import Table

from actionreasoning.runs.run import RunConfig, run_eval
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial, trial_world
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


def steps_per_second(spec: TrialSpec, steps: int) -> float:
    """Raw physics steps per second of a trial's scene, best of three."""
    best = 0.0
    with trial_world(spec) as made:
        scene = made.scene
        for _ in range(3):
            started = time.perf_counter()
            scene.step(steps)
            best = max(best, steps / (time.perf_counter() - started))
    return best


def seconds_per_trial(method: Method, pattern: str, trials: int) -> tuple[float, float]:
    """Mean wall seconds and sim steps of one trial of ``method``."""
    goal = load_pattern(pattern, SceneSpec())
    seconds, steps = [], []
    for trial in range(trials):
        spec = TrialSpec(method=method, pattern_name=pattern, goal=goal, run_seed=0, trial=trial)
        started = time.perf_counter()
        run = run_trial(spec)
        seconds.append(time.perf_counter() - started)
        steps.append(run.result.sim_steps)
    return sum(seconds) / trials, sum(steps) / trials


def eval_wall_time(pattern: str, trials: int, workers: int, out: Path) -> tuple[float, list[str]]:
    """Wall seconds of a classical eval run and its sorted results lines."""
    config = RunConfig(
        method=Method.CLASSICAL,
        pattern_name=pattern,
        goal=load_pattern(pattern, SceneSpec()),
        trials=trials,
        seed=0,
        out=out,
        workers=workers,
    )
    started = time.perf_counter()
    run_eval(config)
    return time.perf_counter() - started, sorted((out / "results.jsonl").read_text().splitlines())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pattern", default="pyramid")
    parser.add_argument("--trials", type=int, default=2, help="trials per method")
    parser.add_argument("--speedup-trials", type=int, default=4)
    parser.add_argument("--steps", type=int, default=5000)
    args = parser.parse_args()
    console = Console()
    goal = load_pattern(args.pattern, SceneSpec())
    spec = TrialSpec(
        method=Method.AGENTS, pattern_name=args.pattern, goal=goal, run_seed=0, trial=0
    )
    console.print(f"physics: {steps_per_second(spec, args.steps):,.0f} steps/s")

    table = Table(title=f"one trial on {args.pattern}, one process ({args.trials} trials each)")
    for column in ("method", "s / trial", "sim steps / trial", "steps / s in a trial"):
        table.add_column(column, justify="right")
    for method in Method:
        seconds, steps = seconds_per_trial(method, args.pattern, args.trials)
        table.add_row(str(method), f"{seconds:.1f}", f"{steps:,.0f}", f"{steps / seconds:,.0f}")
    console.print(table)

    with tempfile.TemporaryDirectory() as root:
        one, serial = eval_wall_time(args.pattern, args.speedup_trials, 1, Path(root) / "w1")
        two, parallel = eval_wall_time(args.pattern, args.speedup_trials, 2, Path(root) / "w2")
    if serial != parallel:
        raise SystemExit("workers 1 and 2 gave different results: a determinism bug")
    console.print(
        f"classical eval of {args.speedup_trials} trials: {one:.1f} s with 1 worker, "
        f"{two:.1f} s with 2 workers: speed-up {one / two:.2f}x (results identical)"
    )


if __name__ == "__main__":
    main()
