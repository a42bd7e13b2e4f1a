"""Physics profiles and perturbations: what PyBullet reads back, seeded draws, true metrics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pybullet as p
import pybullet_data
import pytest
from conftest import assert_clean_error, cli

from actionreasoning.sim.robot_model import FINGER_LEFT, FINGER_RIGHT
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialObserver, TrialSpec, run_trial, trial_world
from actionreasoning.world.noise import NoiseLevel, vary_bricks
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PAPER, PhysicsProfile
from actionreasoning.world.scenarios import NOISE, PHYSICS
from actionreasoning.world.scene_spec import BrickBody, SceneSpec
from actionreasoning.world.stages import StageEvent

NOMINAL = BrickBody(size_m=(0.2, 0.095, 0.06), mass_kg=1.5, lateral_friction=0.5)


def spec_of(physics: PhysicsProfile, noise: NoiseLevel, seed: int = 3) -> TrialSpec:
    goal = load_pattern("pyramid", SceneSpec())
    return TrialSpec(
        method=Method.AGENTS, pattern_name="pyramid", goal=goal, run_seed=seed, trial=0,
        config=TrialConfig(physics=physics, noise=noise),
    )  # fmt: skip


@pytest.mark.parametrize("name", list(PHYSICS))
def test_each_profile_is_what_pybullet_reads_back(name: str) -> None:
    profile = PHYSICS[name]
    with trial_world(spec_of(profile, NOISE["none"])) as world:
        scene, cid = world.scene, world.scene.client
        engine = p.getPhysicsEngineParameters(physicsClientId=cid)
        assert engine["fixedTimeStep"] == pytest.approx(profile.time_step_s)
        assert engine["numSolverIterations"] == profile.solver_iterations
        for body in scene.bricks:
            info = p.getDynamicsInfo(body, -1, physicsClientId=cid)
            assert info[1] == pytest.approx(profile.brick_lateral_friction)
            assert info[6] == pytest.approx(profile.brick_rolling_friction)
            assert info[7] == pytest.approx(profile.brick_spinning_friction)
        ground = p.getDynamicsInfo(scene.ground, -1, physicsClientId=cid)
        assert ground[1] == pytest.approx(profile.ground_lateral_friction)
        for pad in (FINGER_LEFT, FINGER_RIGHT):
            info = p.getDynamicsInfo(scene.robot, pad, physicsClientId=cid)
            assert info[1] == pytest.approx(profile.pad_friction)
            assert info[7] == pytest.approx(profile.pad_spinning_friction)


def test_the_paper_profile_is_pybullets_own_defaults() -> None:
    """A fresh client's engine, a new box's and plane.urdf's contact properties."""
    cid = p.connect(p.DIRECT)
    try:
        engine = p.getPhysicsEngineParameters(physicsClientId=cid)
        p.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=cid)
        plane = p.loadURDF("plane.urdf", physicsClientId=cid)
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1] * 3, physicsClientId=cid)
        box = p.createMultiBody(1.0, shape, physicsClientId=cid)
        box_info = p.getDynamicsInfo(box, -1, physicsClientId=cid)
        plane_info = p.getDynamicsInfo(plane, -1, physicsClientId=cid)
    finally:
        p.disconnect(cid)
    assert PAPER.time_step_s == pytest.approx(engine["fixedTimeStep"])
    assert PAPER.solver_iterations == engine["numSolverIterations"]
    assert PAPER.brick_lateral_friction == box_info[1]
    assert (PAPER.brick_rolling_friction, PAPER.brick_spinning_friction) == box_info[6:8]
    assert PAPER.ground_lateral_friction == plane_info[1]
    assert not PAPER.friction_anchors and PAPER.contact_breaking_threshold_m == 0.02


def test_variation_is_drawn_from_the_trial_seed_within_its_bounds() -> None:
    medium = NOISE["medium"].variation
    first = vary_bricks(medium, [NOMINAL] * 6, trial_seed=5)
    assert first == vary_bricks(medium, [NOMINAL] * 6, trial_seed=5)
    assert first != vary_bricks(medium, [NOMINAL] * 6, trial_seed=6)
    assert len({b.mass_kg for b in first}) == 6
    for body in first:
        assert abs(body.mass_kg / 1.5 - 1.0) <= medium.mass_rel
        assert abs(body.lateral_friction / 0.5 - 1.0) <= medium.friction_rel
        assert (
            max(abs(a - b) for a, b in zip(body.size_m, NOMINAL.size_m, strict=True))
            <= medium.size_m
        )
    assert vary_bricks(NOISE["none"].variation, [NOMINAL] * 2, trial_seed=5) == [NOMINAL] * 2


def perceived(seed: int, noise: NoiseLevel) -> tuple[list, list]:
    """Two observations of the trial's world and its true brick positions."""
    with trial_world(spec_of(PAPER, noise, seed)) as world:
        goal = load_pattern("pyramid", SceneSpec())
        seen = [world.sensor.perceive(goal) for _ in range(2)]
        truth = [world.scene.brick_pose(i)[0] for i in range(len(world.scene.bricks))]
        masses = [p.getDynamicsInfo(b, -1, physicsClientId=world.scene.client)[0]
                  for b in world.scene.bricks]  # fmt: skip
    return [[b.pose.position_m for b in s.bricks] for s in seen], [truth, masses]


def test_perception_noise_is_seeded_and_drawn_anew_per_observation() -> None:
    medium = NOISE["medium"]
    seen, (truth, masses) = perceived(3, medium)
    again, (truth_again, masses_again) = perceived(3, medium)
    other, _ = perceived(4, medium)
    assert seen == again and truth == truth_again and masses == masses_again
    assert seen[0] != seen[1]  # a new draw at every observation
    error = np.subtract(seen[0], truth)
    assert 0.0005 < float(np.std(error)) < 0.005  # medium: 2 mm per axis
    assert seen[0] != other[0]
    assert len(set(masses)) == 6 and all(1.2 <= m <= 1.8 for m in masses)
    clean, (truth, masses) = perceived(3, NOISE["none"])
    assert clean[0] == clean[1] == truth and masses == [1.5] * 6


@pytest.mark.slow
def test_the_same_seed_gives_the_same_line_under_noise_and_metrics_use_true_poses(
    small_pattern: Path,
) -> None:
    goal = load_pattern(small_pattern, SceneSpec())
    truth: dict[int, tuple[float, ...]] = {}

    class AtTheEnd(TrialObserver):
        def stage(self, scene: Scene, event: StageEvent) -> None:
            if event.stage == "final":
                truth.update({i: scene.brick_pose(i)[0] for i in range(len(scene.bricks))})

    spec = TrialSpec(
        method=Method.CLASSICAL, pattern_name="small", goal=goal, run_seed=1, trial=0,
        config=TrialConfig(noise=NOISE["high"]),
    )  # fmt: skip
    first = run_trial(spec, [AtTheEnd()]).result
    again = run_trial(spec).result
    assert first.model_dump_json() == again.model_dump_json()
    assert first.physics == "paper" and first.noise == "high"
    for brick in first.bricks:
        assert brick.final_position == truth[brick.id]


def test_a_physics_or_noise_file_with_a_bad_field_is_refused_in_one_line(tmp_path: Path) -> None:
    physics = tmp_path / "physics.yaml"
    physics.write_text(PAPER.model_copy(update={"name": "mine"}).model_dump_json())
    physics = physics.rename(tmp_path / "physics.json")
    data = json.loads(physics.read_text())
    data["solver_iterations"] = 0
    physics.write_text(json.dumps(data))
    noise = tmp_path / "noise.yaml"
    noise.write_text("name: shaky\nperception: {position_std_m: -1}\n")
    out = str(tmp_path / "out")
    assert_clean_error(
        cli("eval", "--physics", str(physics), "--out", out), "physics.json", "solver_iterations"
    )
    assert_clean_error(
        cli("eval", "--noise", str(noise), "--out", out), "noise.yaml", "perception.position_std_m"
    )
    assert_clean_error(cli("eval", "--physics", "papr", "--out", out), "unknown physics", "paper")
    assert_clean_error(cli("eval", "--noise", "loud", "--out", out), "unknown noise", "medium")
    data.update(solver_iterations=50, name="paper", time_step_s=0.01)
    physics.write_text(json.dumps(data))
    assert_clean_error(cli("eval", "--physics", str(physics), "--out", out), "built-in profile")
    assert not (tmp_path / "out").exists()
