"""The error a closing grip leaves: what the grasp tolerance eps_g must allow.

    .venv/bin/python bench/grasp_error.py --trials 10

Runs agents trials (built-in reasoner, paper physics, no noise, so that every measurement
is the truth) on the pyramid and the grid, and reads sigma_3's checks from each trial's
transcript: the distance between the tool centre point and the brick's centre, and the
yaw between the pads and the brick, once the pads have closed on a brick at rest. Prints
the largest, the 99th percentile and the median of each.
"""

from __future__ import annotations

import argparse

import numpy as np

from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--trials", type=int, default=10, help="trials per pattern")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    errors: dict[str, list[float]] = {"pose_error_m": [], "pose_error_deg": []}
    for pattern in ("pyramid", "grid"):
        goal = load_pattern(pattern, SceneSpec())
        for trial in range(args.trials):
            spec = TrialSpec(Method.AGENTS, pattern, goal, args.seed, trial, TrialConfig())
            for call in run_trial(spec).transcript:
                for gate in call.gates:
                    if gate.gate == "sigma3_grasp":
                        for check in gate.checks:
                            errors.get(check.name, []).append(check.value)
    for name, values in errors.items():
        v = np.asarray(values)
        print(
            f"{name}: {len(v)} grasps, largest {v.max():.4g}, "
            f"99th percentile {np.percentile(v, 99):.4g}, median {np.median(v):.4g}"
        )


if __name__ == "__main__":
    main()
