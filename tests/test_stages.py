"""Stages are one enum (world/stages.py) that the agents, the single agent's steps and the
built-in's policies read; Ag5's phase is a field of its memory, shown in its prompt, that
the built-in and the prompt-only reference model read; tools are called through their
typed handles."""

from __future__ import annotations

import json
from typing import get_args

import pytest
from conftest import built_state

from actionreasoning.agents.memory import PlacementPhase, TaskMemory
from actionreasoning.agents.outputs import SingleAgentStep
from actionreasoning.agents.prompt import render_prompt
from actionreasoning.agents.reasoner import Briefing
from actionreasoning.agents.spec import SINGLE_AGENT, agent_specs
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.view import StateView
from actionreasoning.reasoners import reference_model
from actionreasoning.reasoners.builtin import POLICIES
from actionreasoning.tools.placement import PLACEMENT_POSE, HeldPose, PlacementQuery
from actionreasoning.world.stages import Stage
from actionreasoning.world.tolerances import Tolerances

STATE = built_state("grid")
PLACEMENT = agent_specs(ToolTier.SOLVE)[4]  # placement_pose is a solve-tier tool


def test_the_six_agents_are_the_stages_but_transfer_and_retreat_in_order() -> None:
    keys = [spec.key for spec in agent_specs()]
    assert all(isinstance(key, Stage) for key in keys)
    assert keys == [stage for stage in Stage if stage not in (Stage.TRANSFER, Stage.RETREAT)]


def test_the_single_agent_answers_the_six_agents_stages() -> None:
    assert get_args(SingleAgentStep) == tuple(spec.key for spec in agent_specs())


def test_the_built_in_has_a_policy_for_every_agent() -> None:
    assert set(POLICIES) == {spec.key for spec in agent_specs()} | {SINGLE_AGENT}


def _placement_prompt(phase: PlacementPhase | None) -> str:
    memory = TaskMemory(current_brick=1, current_target=1, phase=phase, step=Stage.PLACEMENT)
    view = StateView.of(STATE, memory, PLACEMENT.scope, PLACEMENT.robot_extras)
    return render_prompt(PLACEMENT, view, memory, Tolerances())


@pytest.mark.parametrize(
    ("phase", "approach"), [(PlacementPhase.CARRY, "joint"), (PlacementPhase.SET_DOWN, "linear")]
)
def test_ag5_reads_its_phase_from_the_prompt(phase: PlacementPhase, approach: str) -> None:
    """The phase is in Ag5's memory block; read from the text, it decides how the
    placement_pose tool is asked (joint to carry, linear once over the slot)."""
    prompt = _placement_prompt(phase)
    assert f'"phase":"{phase}"' in prompt
    answer = json.loads(reference_model.reply([{"role": "user", "content": prompt}]))
    (call,) = answer["tool_calls"]
    assert call == {
        "name": "placement_pose",
        "arguments": {"brick_id": 1, "target_index": 1, "approach": approach},
    }


def test_without_a_phase_ag5_cannot_answer() -> None:
    prompt = _placement_prompt(None)
    assert '"phase"' not in prompt
    with pytest.raises(reference_model.UnreadableConversation, match="no placement phase"):
        reference_model.reply([{"role": "user", "content": prompt}])


def test_a_typed_tool_call_goes_by_name_with_json_arguments_and_checks_its_result() -> None:
    sent: list[tuple[str, object]] = []
    held = HeldPose(
        held=True, offset_in_hand_m=(0, 0, 0), quat_in_hand_xyzw=(1, 0, 0, 0), tilt_in_hand_deg=0
    )

    def runner(name: str, arguments: object) -> HeldPose:
        sent.append((name, arguments))
        return held

    memory = TaskMemory()
    view = StateView.of(STATE, memory, PLACEMENT.scope)
    briefing = Briefing(Stage.PLACEMENT, view, memory, Tolerances(), runner)
    query = PlacementQuery(brick_id=2, target_index=0, approach="linear")
    with pytest.raises(TypeError, match="placement_pose answered a HeldPose"):
        briefing.use(PLACEMENT_POSE, query)
    assert sent == [("placement_pose", {"brick_id": 2, "target_index": 0, "approach": "linear"})]
