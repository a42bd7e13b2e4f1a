"""A pattern that passes validation can be laid out in the pick area for every seed; one
with more bricks than the area holds is refused up front, by `pattern` and `eval` alike."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_clean_error, cli

from actionreasoning.trial.rules import Method, trial_seed
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.world.layout import pick_capacity, sample_pick_poses
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec

SPEC = SceneSpec()
L, W, H = SPEC.brick_size_m


def wall(path: Path, layers: int, per_layer: int = 4, extra: int = 0) -> Path:
    """Rows of ``per_layer`` bricks, joints aligned, ``layers`` high, then ``extra`` bricks
    on top of the first ones."""
    pitch = L + 0.02
    row = [(i - (per_layer - 1) / 2) * pitch for i in range(per_layer)]
    bricks = [
        {"position": [x, 0.0, (k + 0.5) * H], "yaw_deg": 0} for k in range(layers) for x in row
    ]
    bricks += [{"position": [x, 0.0, (layers + 0.5) * H], "yaw_deg": 0} for x in row[:extra]]
    path.write_text(json.dumps({"name": path.stem, "brick_size": [L, W, H], "bricks": bricks}))
    return path


def assert_laid_out(poses: list, count: int, size: tuple[float, float, float]) -> None:
    """``count`` poses on the ground in the pick area, every two the spacing apart."""
    assert len(poses) == count
    centres = np.array([pose.position_m[:2] for pose in poses])
    gaps = np.linalg.norm(centres[:, None] - centres[None], axis=-1) + np.eye(count)
    assert gaps.min() >= SPEC.pick_spacing_m(size)
    for pose in poses:
        x, y, z = pose.position_m
        radius = math.hypot(x, y)
        assert SPEC.pick_radius_m[0] - 1e-9 <= radius <= SPEC.pick_radius_m[1] + 1e-9
        azimuth = math.degrees(math.atan2(y, x))
        assert SPEC.pick_azimuth_deg[0] - 1e-9 <= azimuth <= SPEC.pick_azimuth_deg[1] + 1e-9
        assert z == pytest.approx(size[2] / 2)


def test_eight_bricks_are_laid_out_for_every_seed(tmp_path: Path) -> None:
    goal = load_pattern(wall(tmp_path / "eight.json", layers=2), SPEC)
    assert len(goal.targets) == 8
    # Random draws alone jammed in trials 1, 2, 5, 6, 8, 13 and 18 of run seed 0.
    for trial in range(20):
        rng = np.random.default_rng(trial_seed(0, trial))
        poses = sample_pick_poses(rng, 8, SPEC)
        assert_laid_out(poses, 8, SPEC.brick_size_m)
        assert poses == sample_pick_poses(np.random.default_rng(trial_seed(0, trial)), 8, SPEC)


def test_trial_one_of_the_eight_brick_pattern_gets_its_scene(tmp_path: Path) -> None:
    goal = load_pattern(wall(tmp_path / "eight.json", layers=2), SPEC)
    spec = TrialSpec(method=Method.CLASSICAL, pattern_name="eight", goal=goal, run_seed=0, trial=1)
    with trial_world(spec) as world:
        assert len(world.scene.bricks) == 8


@pytest.mark.parametrize("size", [SPEC.brick_size_m, (0.24, 0.115, 0.071), (0.3, 0.12, 0.085)])
def test_as_many_bricks_as_the_area_holds_are_laid_out_for_every_seed(
    size: tuple[float, float, float],
) -> None:
    capacity = pick_capacity(SPEC, size)
    assert capacity >= 6  # a pyramid of any brick size allowed fits
    for seed in range(10):
        poses = sample_pick_poses(np.random.default_rng(seed), capacity, SPEC, size)
        assert_laid_out(poses, capacity, size)


def test_pattern_and_eval_refuse_more_bricks_than_the_pick_area_holds(tmp_path: Path) -> None:
    path = wall(tmp_path / "thirteen.json", layers=3, extra=1)
    capacity = pick_capacity(SPEC, SPEC.brick_size_m)
    assert capacity == 12
    reason = "bricks: 13 bricks, but the pick area holds at most 12 bricks of (0.200, 0.095, 0.060)"
    checked = cli("pattern", str(path))
    assert_clean_error(checked, "thirteen.json", reason)
    out = tmp_path / "out"
    run = cli("eval", "--method", "classical", "--pattern", str(path), "--out", str(out))
    assert_clean_error(run, "thirteen.json", reason)
    assert run.stderr == checked.stderr
    assert not out.exists()
    assert cli("pattern", str(wall(tmp_path / "twelve.json", layers=3))).returncode == 0
