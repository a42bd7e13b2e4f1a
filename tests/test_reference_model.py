"""The prompt-only reference model: it answers from the messages' text alone, as well as the
built-in reasoner answers from objects, and fails when a fact it needs is cut from a prompt.
"""

from __future__ import annotations

import json
import re
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from conftest import SMALL_PATTERN, cli

from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.tiers import ToolTier
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.control.waypoint import WaypointController
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.chat import ChatReply, ChatRequest, user_message
from actionreasoning.reasoners.llm import LLMLimits, LLMReasoner
from actionreasoning.reasoners.reference_model import UnreadableConversation, reply
from actionreasoning.reasoners.reference_server import ReferenceServer
from actionreasoning.records import LLMUsage
from actionreasoning.trial.first_prompt import first_prompt
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.session import Conditions
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.pictures import Picture
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.stages import Stage

ONE_BRICK = {**SMALL_PATTERN, "name": "one", "bricks": SMALL_PATTERN["bricks"][:1]}


@dataclass
class InProcess:
    """The reference model behind the chat interface, in this process, keeping every
    conversation it was sent."""

    label: str = "reference"
    conversations: list[list[dict[str, str]]] = field(default_factory=list)

    def complete(self, request: ChatRequest) -> ChatReply:
        messages = [dict(m) for m in request.messages]
        self.conversations.append(messages)
        return ChatReply(content=reply(messages), usage=LLMUsage(calls=1))


@dataclass
class Both:
    """Asks the built-in reasoner and the reference model the same request; acts on the
    reference model's answer and keeps both."""

    model: InProcess = field(default_factory=InProcess)
    pairs: list[tuple[str, list, list]] = field(default_factory=list)
    name: str = "both"

    def decide(self, request: AgentRequest) -> AgentReply:
        builtin = BuiltinReasoner().decide(request).answer
        read = LLMReasoner(self.model, LLMLimits(tool_turns=3, repairs=0)).decide(request)
        self.pairs.append((request.spec.key, _numbers(builtin), _numbers(read.answer)))
        return read


def _numbers(answer) -> list:
    """An answer's fields without its rationale, flattened to a list of leaves."""
    data = answer.model_dump(mode="json", exclude={"rationale", "tool_calls"})
    leaves: list = []

    def walk(value) -> None:
        if isinstance(value, dict):
            for key in sorted(value):
                leaves.append(key)
                walk(value[key])
        elif isinstance(value, list):
            for item in value:
                walk(item)
        else:
            leaves.append(value)

    walk(data)
    return leaves


def build_wall(tmp_path_factory: pytest.TempPathFactory, tier: ToolTier) -> Both:
    """The small three-brick wall built by the reference model in ``tier``, the built-in
    asked alongside."""
    pattern = tmp_path_factory.mktemp("pattern") / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    goal = load_pattern(str(pattern), SceneSpec())
    spec = TrialSpec(method=Method.AGENTS, pattern_name="small", goal=goal, run_seed=0, trial=0)
    both = Both()
    with trial_world(spec) as made:
        world = SimWorld(WaypointController(made.scene, made.arm), goal, made.sensor)
        result = Orchestrator(world, both, tier=tier).build(goal)
    assert result.failure is None and sorted(result.placements) == [0, 1, 2]
    return both


@pytest.fixture(scope="module")
def wall_run(tmp_path_factory: pytest.TempPathFactory) -> Both:
    """The wall in the solve tier, whose tools return what these tests cut."""
    return build_wall(tmp_path_factory, ToolTier.SOLVE)


#: The tool calls of one brick in each tier: the solve tier's tools answer Ag1 and Ag5 (at
#: the set-down twice: the slot, then the slot for the brick's further roll by touch-down);
#: in the check tier Ag1 checks its grasp (Ag5 composes the slot, the gate checks its way);
#: without tools, none.
TOOL_CALLS = {
    ToolTier.SOLVE: ["grasp_options", "placement_pose", "placement_pose", "placement_pose"],
    ToolTier.CHECK: ["collision_check", "collision_check", "reachability"],
    ToolTier.NONE: [],
}


@pytest.mark.slow
@pytest.mark.parametrize("tier", list(ToolTier))
def test_read_from_the_text_the_answers_are_the_built_in_reasoners(
    tmp_path_factory: pytest.TempPathFactory, wall_run: Both, tier: ToolTier
) -> None:
    run = wall_run if tier is ToolTier.SOLVE else build_wall(tmp_path_factory, tier)
    agents = [agent for agent, _, _ in run.pairs]
    cycle = ["pre_grasp", "descent", "grasp", "lift", "placement", "placement", "release"]
    assert agents == cycle * 3
    for agent, builtin, read in run.pairs:
        # The prompt rounds to 0.01 mm and 1e-5: the same decisions to within that.
        assert read == pytest.approx(builtin, abs=1e-3), agent
    asked = [
        call["name"]
        for conversation in run.model.conversations
        if len(conversation) > 1
        for call in json.loads(conversation[1]["content"])["tool_calls"]
    ]
    assert asked == TOOL_CALLS[tier] * 3


@pytest.mark.slow
def test_it_calls_tools_as_a_language_model_does(wall_run: Both) -> None:
    tool_turns = [c for c in wall_run.model.conversations if len(c) > 1]
    asked = [json.loads(c[1]["content"])["tool_calls"][0]["name"] for c in tool_turns]
    assert asked == TOOL_CALLS[ToolTier.SOLVE] * 3
    assert all(c[2]["content"].startswith("Tool results: [") for c in tool_turns)


def _conversation(run: Both, heading: str, turns: int) -> list[dict[str, str]]:
    return next(
        c
        for c in run.model.conversations
        if c[0]["content"].startswith(heading) and len(c) == turns
    )


@pytest.mark.slow
def test_without_the_ready_pose_in_the_state_it_cannot_answer(wall_run: Both) -> None:
    release = _conversation(wall_run, "# Agent 6 of 6", 1)
    assert json.loads(reply(release))["waypoint"]["position_m"] == [0.45, -0.25, 0.4]
    prompt = release[0]["content"]
    cut = re.sub(r',"ready_pose":\{"position_m":\[[^]]*\],"quat_xyzw":\[[^]]*\]\}', "", prompt)
    assert cut != prompt
    with pytest.raises(UnreadableConversation, match="ready pose"):
        reply([{"role": "user", "content": cut}])


@pytest.mark.slow
def test_without_the_slot_pose_in_the_tool_result_it_cannot_answer(wall_run: Both) -> None:
    placement = _conversation(wall_run, "# Agent 5 of 6", 3)
    answer = json.loads(reply(placement))
    assert answer["waypoint"]["position_m"] and "tool_calls" not in answer
    result = placement[2]["content"]
    cut = re.sub(r'"slot_pose":\{[^}]*\},', "", result)
    assert cut != result
    with pytest.raises(UnreadableConversation, match="slot_pose"):
        reply([*placement[:2], {"role": "user", "content": cut}])


@pytest.mark.slow
def test_a_threshold_it_is_not_shown_is_never_guessed(wall_run: Both) -> None:
    pre_grasp = _conversation(wall_run, "# Agent 1 of 6", 3)
    assert json.loads(reply(pre_grasp))["brick_id"] == 0
    prompt = pre_grasp[0]["content"]
    cut = re.sub(r"^- c_min_m = .*\n", "", prompt, flags=re.M)
    assert cut != prompt
    answer = json.loads(reply([{"role": "user", "content": cut}, *pre_grasp[1:]]))
    # Without c_min_m it cannot tell brick 0's approach clearance is enough, so it looks
    # at the next brick rather than assume a default it was not told.
    assert "brick_id" not in answer
    assert answer["tool_calls"][0]["arguments"]["brick_id"] == 1


@pytest.fixture
def server() -> Iterator[str]:
    served = ReferenceServer(port=0)
    thread = threading.Thread(target=served.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    yield served.url
    served.shutdown()
    served.server_close()


@pytest.mark.slow
@pytest.mark.parametrize("tier", list(ToolTier))
def test_over_http_it_builds_a_brick_with_tool_calls_and_usage(
    server: str, tmp_path: Path, tier: ToolTier
) -> None:
    pattern = tmp_path / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    out = tmp_path / "run"
    result = cli(
        "eval", "--pattern", str(pattern), "--trials", "1", "--seed", "0", "--out", str(out),
        "--llm", "openai:reference", "--base-url", server, "--transcripts", "--tools", tier,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    line = json.loads((out / "results.jsonl").read_text())
    assert line["success"] and line["llm"] == "openai:reference"
    assert line["fallback_decisions"] == 0 and line["decisions"] == 7
    assert line["llm_usage"]["prompt_tokens"] > 0 and line["llm_usage"]["completion_tokens"] > 0
    calls = [
        AgentCall.model_validate_json(text)
        for text in (out / "transcripts" / "trial_000.jsonl").read_text().splitlines()
    ]
    turns = {ToolTier.SOLVE: [1, 0, 0, 0, 1, 2, 0], ToolTier.CHECK: [1, 0, 0, 0, 0, 0, 0]}
    assert [c.tool_turns for c in calls] == turns.get(tier, [0] * 7)
    assert [t.name for c in calls for t in c.tool_calls] == TOOL_CALLS[tier]
    assert all(c.usage.prompt_tokens > 0 and not c.fallback for c in calls)


@pytest.fixture(scope="module")
def image_prompt() -> tuple[str, tuple[Picture, ...]]:
    """Agent 1's first image-tier prompt (no tools) of pyramid trial 0 and its pictures."""
    conditions = Conditions.load("pyramid", tools="none", observe="image")
    return first_prompt(conditions.spec(0, 0), Stage.PRE_GRASP)


def test_an_image_prompt_is_answered_from_its_pictures_naming_no_brick(
    image_prompt: tuple[str, tuple[Picture, ...]],
) -> None:
    prompt, pictures = image_prompt
    assert '"bricks"' not in prompt and "Observation: image" in prompt
    answer = json.loads(reply([user_message(prompt, pictures)]))
    assert "brick_id" not in answer and answer["target_index"] == 0
    assert len(answer["waypoint"]["position_m"]) == 3


@pytest.mark.parametrize(
    ("broken", "reason"),
    [
        (lambda ps: (), "names 5 pictures and its message carries 0"),
        (lambda ps: ps[:4], "names 5 pictures and its message carries 4"),
        (lambda ps: (*ps[:4], Picture("pick_side", ps[4].kind, b"not a png")), "pick_side.depth"),
    ],
    ids=["none", "one short", "not a png"],
)
def test_an_image_prompt_without_its_pictures_cannot_be_answered(
    image_prompt: tuple[str, tuple[Picture, ...]],
    broken: Callable[[tuple[Picture, ...]], tuple[Picture, ...]],
    reason: str,
) -> None:
    prompt, pictures = image_prompt
    with pytest.raises(UnreadableConversation, match=re.escape(reason)):
        reply([user_message(prompt, broken(pictures))])
