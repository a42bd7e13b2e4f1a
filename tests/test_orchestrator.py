"""The gated orchestrator with the built-in reasoner, in the real simulator."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import pytest

from actionreasoning.agents.orchestrator import Orchestrator, target_supports
from actionreasoning.agents.outputs import PreGraspAnswer
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.eval.metrics import center_offset_cm
from actionreasoning.eval.sim_world import SimWorld
from actionreasoning.eval.trial import READY_POSE, Method, TrialSpec, trial_world
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec


@pytest.fixture
def small_goal(small_pattern: Path):
    return load_pattern(small_pattern, SceneSpec())


@dataclass
class Scripted:
    """Answers pre-grasp with scripted answers first, then like the built-in reasoner."""

    pre_grasp: list[PreGraspAnswer]
    name: str = "scripted"
    builtin: BuiltinReasoner = field(default_factory=lambda: BuiltinReasoner(READY_POSE))
    requests: list[AgentRequest] = field(default_factory=list)

    def decide(self, request: AgentRequest) -> AgentReply:
        self.requests.append(request)
        if request.spec.key == "pre_grasp" and self.pre_grasp:
            return AgentReply(answer=self.pre_grasp.pop(0))
        return self.builtin.decide(request)


def build(goal, reasoner):
    spec = TrialSpec(method=Method.AGENTS, pattern_name="small", goal=goal, run_seed=4, trial=0)
    with trial_world(spec) as (scene, arm, _):
        result = Orchestrator(SimWorld(WaypointController(scene, arm), goal), reasoner).build(goal)
        scene.step(scene.ticks_for(1.0))
        final = [scene.brick_pose(i)[0] for i in range(len(scene.bricks))]
    return result, final


def test_supports_of_the_goal() -> None:
    goal = load_pattern("pyramid", SceneSpec())
    assert target_supports(goal) == {0: (), 1: (), 2: (), 3: (0, 1), 4: (1, 2), 5: (3, 4)}


@pytest.mark.slow
def test_a_refused_target_gets_feedback_and_the_wall_is_built(small_goal) -> None:
    too_early = PreGraspAnswer(brick_id=0, target_index=2, waypoint=None)
    reasoner = Scripted(pre_grasp=[too_early])
    result, final = build(small_goal, reasoner)
    assert result.failure is None
    assert sorted(result.placements) == [0, 1, 2]
    assert result.decisions == 3 * 6 + 1
    retried = [r for r in reasoner.requests if r.spec.key == "pre_grasp"][1]
    assert retried.memory.last_feedback == "the answer needs brick_id, target_index and waypoint"
    for target, brick in result.placements.items():
        assert center_offset_cm(final[brick], small_goal.targets[target].pose.position_m) < 0.1


def test_a_spent_budget_is_a_typed_failure(small_goal) -> None:
    unbuilt = PreGraspAnswer(brick_id=0, target_index=2, waypoint=READY_POSE.model_dump())
    reasoner = Scripted(pre_grasp=[unbuilt] * 3)
    result, _ = build(small_goal, reasoner)
    assert result.failure is not None
    assert result.failure.reason == "budget_exhausted"
    assert result.failure.agent == "pre_grasp"
    assert "target 2 rests on targets [0, 1], not built yet" in result.failure.detail
    assert result.placements == {}
