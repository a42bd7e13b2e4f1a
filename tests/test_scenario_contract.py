"""The contract every built-in scenario keeps, as dm_control tests every task of
``manipulation.ALL`` and Gymnasium's checker every env: for each of the paper's patterns x
method x physics profile x noise level of the registry (world/scenarios.py), a run of two
trials writes lines
that meet ``actionreasoning schema results`` and name their scenario, and, killed after its
first line and run again, writes the same lines: the resumed trial, run a second time from
the same seed, gives the same line.

The agents and the single agent build on the fake world (fake_world.py: kinematic, exact
measurements, no physics; the bricks laid out, told and gated as the scenario has them);
the classical script, which drives the simulator itself, runs in it. The fast suite runs
four fake-world cases that hold each of these patterns, every profile and level
(``_fast_cases``); the other cases are slow. A wall's trial takes minutes: the built-in
``wall`` is loaded and validated in test_walls.py, made into an env in test_gym_env.py and
its prompts linted in test_prompt_lint.py.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict
from pathlib import Path

import numpy as np
import pytest
from conftest import cli
from fake_world import FakeWorld
from jsonschema import Draft202012Validator

from actionreasoning.runs import jobs
from actionreasoning.runs.run import RunConfig, run_eval
from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.trial.rules import Method, trial_seed
from actionreasoning.trial.runner import TrialObserver, TrialRun, TrialSpec, measure, run_agents
from actionreasoning.trial.session import Conditions
from actionreasoning.world.scenarios import NOISE, PHYSICS, SCENARIOS, Scenario
from actionreasoning.world.supply import lay_out

#: The methods the fake world runs (it stands in for the agents' World, not for the scene
#: the classical script drives).
ON_FAKE_WORLD = (Method.AGENTS, Method.SINGLE_AGENT)
#: The patterns whose trials this contract runs: the paper's six-brick ones.
SIMULATED = ("pyramid", "grid")


def _fast_cases() -> Iterator[tuple[Scenario, Method]]:
    """Fake-world cases that hold every pattern, profile and level at least once: the first
    with the six agents, the others with the single agent (a sixth of their cost)."""
    kinds = [list(SIMULATED), list(PHYSICS), list(NOISE)]
    for i in range(max(map(len, kinds))):
        pattern, physics, noise = (kind[i % len(kind)] for kind in kinds)
        yield Scenario(pattern, physics, noise), Method.AGENTS if i == 0 else Method.SINGLE_AGENT


FAST = set(_fast_cases())
CASES = [
    pytest.param(
        scenario,
        method,
        marks=() if (scenario, method) in FAST else pytest.mark.slow,
        id=f"{scenario}-{method}",
    )
    for scenario in SCENARIOS
    if scenario.pattern in SIMULATED
    for method in Method
]


@pytest.fixture(scope="module")
def results_schema() -> Draft202012Validator:
    """What ``actionreasoning schema results`` prints."""
    printed = cli("schema", "results")
    assert printed.returncode == 0, printed.stderr
    return Draft202012Validator(json.loads(printed.stdout))


def on_fake_world(
    kinematics: tuple[KinematicArm, CollisionChecker],
) -> Callable[[TrialSpec, Sequence[TrialObserver]], TrialRun]:
    """``run_trial`` with the fake world in place of the simulator, for the agents' methods:
    the bricks laid out from the trial's seed as the scene lays them out, with the profile's
    friction, gated for the level's sensing noise (measured exactly)."""

    def run_trial(spec: TrialSpec, observers: Sequence[TrialObserver] = ()) -> TrialRun:
        assert not observers, "the fake world feeds no observers"
        config, goal, seed = spec.config, spec.goal, trial_seed(spec.run_seed, spec.trial)
        size = goal.brick_size_m
        nominal = config.scene.brick_body(config.physics.brick_lateral_friction, size)
        sizes = [target.size_m for target in goal.targets]
        heights = [s[2] for s in sizes]
        rng = np.random.default_rng(seed)
        poses = lay_out(goal.supply, sizes, heights, config.scene, rng).poses
        world = FakeWorld(
            goal,
            poses,
            *kinematics,
            spec=config.scene,
            mass_kg=nominal.mass_kg,
            friction=nominal.lateral_friction,
        )
        world.sensing = config.noise.sensing()
        outcome = run_agents(world, spec, stage=lambda brick, stage: None)
        return TrialRun(measure(spec, seed, world, outcome, None), tuple(outcome.transcript))

    return run_trial


@pytest.mark.parametrize(("scenario", "method"), CASES)
def test_a_scenario_writes_valid_lines_again_on_resume(
    scenario: Scenario,
    method: Method,
    tmp_path: Path,
    results_schema: Draft202012Validator,
    kinematics: tuple[KinematicArm, CollisionChecker],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    if method in ON_FAKE_WORLD:
        monkeypatch.setattr(jobs, "run_trial", on_fake_world(kinematics))
    conditions = Conditions.load(**asdict(scenario))
    config = RunConfig(
        method=method,
        pattern_name=conditions.pattern_name,
        goal=conditions.goal,
        trials=2,
        seed=0,
        out=tmp_path / "run",
        config=conditions.config,
    )
    run_eval(config)
    results = config.out / "results.jsonl"
    lines = results.read_text().splitlines(keepends=True)
    assert len(lines) == 2
    for trial, line in enumerate(lines):
        written = json.loads(line)
        results_schema.validate(written)
        named = {key: written[key] for key in ("pattern", "physics", "noise", "method", "trial")}
        assert named == {**asdict(scenario), "method": method, "trial": trial}

    results.write_text(lines[0])  # killed after the first trial's line
    summary = run_eval(config)
    assert summary.resumed_trials == 1
    assert results.read_text().splitlines(keepends=True) == lines
