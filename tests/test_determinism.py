"""The same seed gives the same trial, and observing the simulation does not change it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from actionreasoning.eval.run import RunConfig, run_eval
from actionreasoning.eval.trial import Method, trial_seed
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


def run(out: Path, pattern: Path, method: Method, snapshots: bool) -> str:
    goal = load_pattern(pattern, SceneSpec())
    config = RunConfig(
        method=method,
        pattern_name=str(pattern),
        goal=goal,
        trials=1,
        seed=11,
        out=out,
        snapshots=snapshots,
    )
    run_eval(config)
    return (out / "results.jsonl").read_text()


def test_trial_seeds_depend_only_on_run_seed_and_index() -> None:
    assert trial_seed(0, 3) == trial_seed(0, 3)
    assert len({trial_seed(s, k) for s in range(5) for k in range(20)}) == 100


@pytest.mark.slow
@pytest.mark.parametrize(("method", "stages"), [(Method.CLASSICAL, 8), (Method.AGENTS, 6)])
def test_same_seed_same_results_with_and_without_snapshots(
    tmp_path: Path, small_pattern: Path, method: Method, stages: int
) -> None:
    first = run(tmp_path / "a", small_pattern, method, snapshots=False)
    second = run(tmp_path / "b", small_pattern, method, snapshots=False)
    observed = run(tmp_path / "c", small_pattern, method, snapshots=True)
    assert first == second
    assert first == observed
    assert json.loads(first)["success"]
    pictures = sorted((tmp_path / "c" / "snapshots" / "trial_000").glob("*.png"))
    assert len(pictures) == 3 * stages + 3  # every stage of 3 bricks, two final views, the sheet
