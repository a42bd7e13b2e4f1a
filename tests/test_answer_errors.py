"""eval --answer-errors: each kind of mistake changes exactly what it says, the draws come
from the trial's seed and the call's index, and corrupted calls are marked in transcripts.

The answers corrupted are real ones: the built-in reasoner's, asked by the real orchestrator
and the single agent on the scripted FakeWorld (no physics)."""

from __future__ import annotations

import itertools
import json
import math
import subprocess
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import DOCS, SMALL_PATTERN, assert_clean_error, cli, doc_table
from fake_world import FakeWorld
from scipy.spatial.transform import Rotation

from actionreasoning.agents.answer_errors import (
    GUARDING_TOLERANCES,
    NEAR_MISS_FACTORS,
    NEAR_MISSES,
    AnswerCorruption,
    AnswerErrors,
    Caught,
    CorruptionKind,
    parse_kinds,
)
from actionreasoning.agents.calls import BuildResult
from actionreasoning.agents.catches import premove_refusals
from actionreasoning.agents.feedback import Refusal
from actionreasoning.agents.memory import PlacedBrick, PlacementPhase
from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.outputs import AgentAnswer, LiftAnswer, PreGraspAnswer, ToolCall
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Reasoner
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.transcript import AgentCall, CheckRecord, GateRecord, Outcome
from actionreasoning.agents.verification import Verification, judged_after_move
from actionreasoning.agents.view import target_supports
from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.imperfect import (
    ANSWER_ERROR_STREAM,
    CM_AS_M_FACTOR,
    ImperfectReasoner,
    corruption,
    repeated,
)
from actionreasoning.runs.summary import summarize, summary_markdown
from actionreasoning.trial.results import AnswerErrorCounts, PlacementMetrics, TrialResult
from actionreasoning.world import noise
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.stages import Stage
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import Tolerances

SPEC = SceneSpec()
BRICKS = sample_pick_poses(np.random.default_rng(0), 3, SPEC)
ALL = tuple(CorruptionKind)


@dataclass
class Recorder:
    """A reasoner that keeps every request it was asked with its reply."""

    inner: Reasoner = field(default_factory=BuiltinReasoner)
    name: str = "recorder"
    seen: list[tuple[AgentRequest, AgentReply]] = field(default_factory=list)

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = self.inner.decide(request)
        self.seen.append((request, reply))
        return reply


@dataclass(frozen=True)
class Exchange:
    """One request and the built-in reasoner's answer to it."""

    request: AgentRequest
    answer: AgentAnswer

    @property
    def step(self) -> str:
        return str(getattr(self.answer, "step", self.request.spec.key))

    @property
    def placed(self) -> int:
        return len(self.request.memory.placed)


def recorded(runner: Callable[[FakeWorld, Reasoner], Any], world: FakeWorld) -> list[Exchange]:
    recorder = Recorder()
    runner(world, recorder).build(world.goal)
    return [Exchange(request, reply.answer) for request, reply in recorder.seen]


@pytest.fixture(scope="module")
def agents(kinematics, wall) -> list[Exchange]:
    """Every call of the six agents building the wall."""
    return recorded(Orchestrator, FakeWorld(wall, BRICKS, *kinematics))


def single_agent(world: FakeWorld, reasoner: Reasoner) -> Orchestrator:
    """The single-agent ablation on ``world``: the merged agent, nothing but validation
    refusing."""
    return Orchestrator(world, reasoner, verify=Verification.NONE, single_agent=True)


@pytest.fixture(scope="module")
def single(kinematics, wall) -> list[Exchange]:
    """Every call of the single agent building the wall."""
    return recorded(single_agent, FakeWorld(wall, BRICKS, *kinematics))


def first(exchanges: list[Exchange], step: str, placed: int | None = 0) -> Exchange:
    """The first call at ``step`` with ``placed`` bricks built (None: any number)."""
    return next(e for e in exchanges if e.step == step and placed in (None, e.placed))


def corrupt(
    exchange: Exchange, kind: CorruptionKind, seed: int = 0
) -> tuple[AgentAnswer, AnswerCorruption]:
    found = corruption(exchange.answer, exchange.request, [kind], np.random.default_rng(seed))
    assert found is not None, f"{kind} does not apply to {exchange.step}"
    return found


def changed(before: AgentAnswer, after: AgentAnswer) -> dict[str, tuple[Any, Any]]:
    """The leaves of the two answers' JSON that differ, by dotted path."""
    old, new = flat(before.model_dump(mode="json")), flat(after.model_dump(mode="json"))
    return {k: (old.get(k), new.get(k)) for k in {*old, *new} if old.get(k) != new.get(k)}


def flat(value: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(value, dict):
        return {
            k: v for name, item in value.items() for k, v in flat(item, f"{prefix}{name}.").items()
        }
    if isinstance(value, list):
        return {
            k: v for i, item in enumerate(value) for k, v in flat(item, f"{prefix}{i}.").items()
        }
    return {prefix.rstrip("."): value}


def displacement(exchange: Exchange, answer: AgentAnswer) -> np.ndarray:
    tool = np.array(exchange.request.state.robot.ee_pose.position_m)
    return np.array(answer.waypoint.position_m) - tool  # type: ignore[attr-defined]


# --- each kind --------------------------------------------------------------------------


@pytest.mark.parametrize(("step", "placed"), [("release", 0), ("pre_grasp", 1), ("descent", 0)])
def test_sign_flip_flips_one_component_of_the_displacement(agents, step, placed) -> None:
    exchange = first(agents, step, placed)
    before = displacement(exchange, exchange.answer)
    for seed in range(8):
        answer, record = corrupt(exchange, CorruptionKind.SIGN_FLIP, seed)
        after = displacement(exchange, answer)
        (axis,) = np.flatnonzero(~np.isclose(before, after))
        assert after[axis] == pytest.approx(-before[axis])
        big = [i for i in (0, 1) if abs(before[i]) >= 0.001]
        assert axis in (big or [2])
        assert set(changed(exchange.answer, answer)) == {f"waypoint.position_m.{axis}"}
        assert record.detail.startswith(f"waypoint.position_m[{axis}] ")
    if step == "descent":  # straight down: the flip sends the tool up
        assert axis == 2 and after[2] > 0


@pytest.mark.parametrize(
    ("kind", "turns"), [(CorruptionKind.YAW_90, {90.0, -90.0}), (CorruptionKind.YAW_180, {180.0})]
)
def test_yaw_turns_the_orientation_about_world_z(agents, kind, turns) -> None:
    exchange = first(agents, "descent")
    old = Rotation.from_quat(exchange.answer.waypoint.quat_xyzw)  # type: ignore[attr-defined]
    seen = set()
    for seed in range(12):
        answer, record = corrupt(exchange, kind, seed)
        assert answer.waypoint.position_m == exchange.answer.waypoint.position_m  # type: ignore[attr-defined]
        new = Rotation.from_quat(answer.waypoint.quat_xyzw)  # type: ignore[attr-defined]
        turn = next(
            t
            for t in turns
            if (Rotation.from_euler("z", t, degrees=True) * old).approx_equal(new, 1e-9)
        )
        seen.add(turn)
        assert {k.rsplit(".", 1)[0] for k in changed(exchange.answer, answer)} == {
            "waypoint.quat_xyzw"
        }
        assert f"turned {turn:+g} deg" in record.detail
    assert seen == turns


def test_cm_as_m_multiplies_the_largest_displacement_component_by_100(agents) -> None:
    exchange = first(agents, "lift")
    before = displacement(exchange, exchange.answer)
    axis = int(np.argmax(np.abs(before)))
    answer, record = corrupt(exchange, CorruptionKind.CM_AS_M)
    after = displacement(exchange, answer)
    assert axis == 2 and after[2] == pytest.approx(CM_AS_M_FACTOR * before[2])
    assert set(changed(exchange.answer, answer)) == {"waypoint.position_m.2"}
    assert record.detail.startswith("waypoint.position_m[2] ")


def test_into_obstacle_goes_to_a_placed_brick_or_into_the_ground(agents) -> None:
    alone = first(agents, "pre_grasp", placed=0)
    answer, record = corrupt(alone, CorruptionKind.INTO_OBSTACLE)
    x, y, _ = alone.answer.waypoint.position_m  # type: ignore[attr-defined]
    assert answer.waypoint.position_m == (x, y, 0.0)  # type: ignore[attr-defined]
    assert "into the ground" in record.detail
    later = first(agents, "pre_grasp", placed=2)
    placed = {b.id: b.pose.position_m for b in later.request.state.bricks if b.status == "placed"}
    assert len(placed) == 2
    hit = set()
    for seed in range(8):
        answer, record = corrupt(later, CorruptionKind.INTO_OBSTACLE, seed)
        brick = next(i for i, p in placed.items() if answer.waypoint.position_m == p)  # type: ignore[attr-defined]
        hit.add(brick)
        assert f"placed brick {brick}" in record.detail
        assert {k.rsplit(".", 1)[0] for k in changed(later.answer, answer)} == {
            "waypoint.position_m"
        }
    assert hit == set(placed)


def test_skipped_hover_lowers_the_approach(agents, single) -> None:
    """The approach is the one answered move that stops above its goal: the carry over the
    slot is a controller primitive for both methods."""
    for exchange in (first(agents, "pre_grasp"), first(single, "pre_grasp")):
        answer, _ = corrupt(exchange, CorruptionKind.SKIPPED_HOVER)
        brick = exchange.request.state.brick(exchange.answer.brick_id)  # type: ignore[attr-defined]
        x, y, _ = exchange.answer.waypoint.position_m  # type: ignore[attr-defined]
        assert answer.waypoint.position_m == (x, y, brick.pose.position_m[2])  # type: ignore[attr-defined]
    for step in ("descent", "lift", "placement", "release"):
        assert not applies(first(agents, step), CorruptionKind.SKIPPED_HOVER)
        assert not applies(first(single, step, None), CorruptionKind.SKIPPED_HOVER)


def test_too_fast_drops_the_duration_of_moves_that_have_one(agents) -> None:
    lift = first(agents, "lift")
    answer, record = corrupt(lift, CorruptionKind.TOO_FAST)
    assert lift.answer.waypoint.duration_s is not None  # type: ignore[attr-defined]
    assert changed(lift.answer, answer) == {
        "waypoint.duration_s": (lift.answer.waypoint.duration_s, None)  # type: ignore[attr-defined]
    }
    assert record.detail.endswith("-> None")
    assert not applies(first(agents, "pre_grasp"), CorruptionKind.TOO_FAST)


def test_wrong_choice_names_a_brick_or_target_that_cannot_be_used(
    agents, single, kinematics, wall
) -> None:
    for exchange in (first(agents, "pre_grasp", placed=0), first(single, "pre_grasp", placed=0)):
        answer, record = corrupt(exchange, CorruptionKind.WRONG_CHOICE)  # nothing placed yet:
        assert changed(exchange.answer, answer) == {"target_index": (0, 2)}  # 2 rests on 0, 1
        assert "support is not built" in record.detail
    later = first(agents, "pre_grasp", placed=1)
    state, memory = later.request.state, later.request.memory
    placed = {b.id for b in state.bricks if b.status == "placed"}
    built = {p.target_index for p in memory.placed}
    supports = target_supports(state.goal)
    unsupported = {t for t, under in supports.items() if t not in built and not set(under) <= built}
    seen = set()
    for seed in range(20):
        answer, _ = corrupt(later, CorruptionKind.WRONG_CHOICE, seed)
        ((name, (_, new)),) = changed(later.answer, answer).items()
        group = (
            "placed"
            if name == "brick_id" and new in placed
            else "built"
            if new in built
            else "unsupported"
        )
        assert name == "target_index" or group == "placed"
        assert group != "unsupported" or new in unsupported
        seen.add(group)
    assert seen == {"placed", "built", "unsupported"}
    one = wall.model_copy(update={"targets": wall.targets[:1]})
    alone = recorded(Orchestrator, FakeWorld(one, BRICKS, *kinematics))[0]
    answer, record = corrupt(alone, CorruptionKind.WRONG_CHOICE)
    assert answer.brick_id == 3 and record.detail.endswith("(no such brick)")  # type: ignore[attr-defined]
    for step in ("descent", "release"):
        assert not applies(first(agents, step), CorruptionKind.WRONG_CHOICE)
    assert not applies(first(single, "descent"), CorruptionKind.WRONG_CHOICE)


def test_missing_field_leaves_out_one_decision_the_answer_made(agents, single) -> None:
    cases = [
        (first(agents, "pre_grasp"), {"waypoint", "brick_id", "target_index"}),
        (first(agents, "descent"), {"waypoint", "gripper_opening_m"}),
        (first(agents, "grasp"), {"close"}),
        (first(agents, "release"), {"waypoint", "gripper_opening_m"}),
        (first(single, "pre_grasp"), {"waypoint", "brick_id", "target_index"}),
        (first(single, "grasp"), {"close"}),
    ]
    for exchange, fields in cases:
        seen = set()
        for seed in range(40):
            answer, record = corrupt(exchange, CorruptionKind.MISSING_FIELD, seed)
            (name,) = {k.split(".", 1)[0] for k in changed(exchange.answer, answer)}
            seen.add(name)
            expected = {"close": False}.get(name)
            assert getattr(answer, name) == expected
            assert record.detail.startswith(name)
        assert seen == fields, exchange.step


def applies(exchange: Exchange, kind: CorruptionKind) -> bool:
    return (
        corruption(exchange.answer, exchange.request, [kind], np.random.default_rng(0)) is not None
    )


def test_answers_no_kind_applies_to_are_left_as_they_are(agents, single) -> None:
    for grasp in (first(agents, "grasp"), first(single, "grasp")):
        assert [k for k in ALL if applies(grasp, k)] == [CorruptionKind.MISSING_FIELD]
    tools = Exchange(
        first(agents, "pre_grasp").request,
        PreGraspAnswer(tool_calls=[ToolCall(name="grasp_options", arguments={"brick_id": 0})]),
    )
    assert not any(applies(tools, k) for k in ALL)
    reasoner = ImperfectReasoner(Fixed(tools.answer), AnswerErrors(rate=1.0), 7)
    reply = reasoner.decide(tools.request)
    assert reply.answer is tools.answer and reply.corruption is None


def test_every_corruption_of_every_answer_keeps_numbers_finite_and_the_original(
    agents, single
) -> None:
    tried = 0
    for exchange in agents + single:
        for kind in ALL:
            for seed in range(3):
                found = corruption(
                    exchange.answer, exchange.request, [kind], np.random.default_rng(seed)
                )
                if found is None:
                    continue
                answer, record = found
                tried += 1
                numbers = [
                    v for v in flat(answer.model_dump(mode="json")).values() if isinstance(v, float)
                ]
                assert all(math.isfinite(v) for v in numbers)
                assert record.kind is kind and record.detail and "\n" not in record.detail
                assert record.original == exchange.answer.model_dump(mode="json")
                assert changed(exchange.answer, answer)
                assert type(answer) is exchange.request.spec.output_model
    assert tried > 300


# --- near-misses ------------------------------------------------------------------------


def test_the_guarding_tolerances_name_tolerance_fields_of_steps() -> None:
    steps = {str(s) for s in Stage}
    assert set(GUARDING_TOLERANCES) <= steps
    for step, names in GUARDING_TOLERANCES.items():
        assert {name for name in names if name} <= set(Tolerances.model_fields), step
    assert set(GUARDING_TOLERANCES) == {str(spec.key) for spec in agent_specs()}
    assert GUARDING_TOLERANCES["release"] == (None, None)
    assert NEAR_MISSES <= set(AnswerErrors().kinds)  # in the default kinds


def test_near_misses_are_off_by_one_to_three_of_the_tolerance_that_guards_the_step(
    agents, single
) -> None:
    low, high = NEAR_MISS_FACTORS
    factors: dict[CorruptionKind, list[float]] = {kind: [] for kind in NEAR_MISSES}
    directions: set[int] = set()
    tried = set()
    for exchange in agents + single:
        guard = GUARDING_TOLERANCES.get(exchange.step, (None, None))
        before = getattr(exchange.answer, "waypoint", None)
        for kind in NEAR_MISSES:
            name = guard[0] if kind is CorruptionKind.NEAR_OFFSET else guard[1]
            if name is None or before is None:
                assert not applies(exchange, kind), (exchange.step, kind)
                continue
            tried.add(exchange.step)
            position, yaw = (
                math.nan if name is None else getattr(exchange.request.tolerances, name)
                for name in guard
            )
            for seed in range(6):
                answer, record = corrupt(exchange, kind, seed)
                after = answer.waypoint  # type: ignore[attr-defined]
                if kind is CorruptionKind.NEAR_OFFSET:
                    shift = np.subtract(after.position_m, before.position_m)
                    assert shift[2] == 0.0 and after.quat_xyzw == before.quat_xyzw
                    factors[kind].append(math.hypot(*shift[:2]) / position)
                    directions.add(int(math.degrees(math.atan2(shift[1], shift[0])) // 90))
                    assert f"x {guard[0]} " in record.detail
                else:
                    assert after.position_m == before.position_m
                    turn = (
                        Rotation.from_quat(after.quat_xyzw)
                        * Rotation.from_quat(before.quat_xyzw).inv()
                    )
                    x, y, z = turn.as_rotvec(degrees=True)
                    assert abs(x) < 1e-6 and abs(y) < 1e-6
                    factors[kind].append(abs(z) / yaw)
                    directions.add(int(np.sign(z)) + 10)
                    assert f"x {guard[1]} " in record.detail
    assert tried == {"pre_grasp", "descent", "lift", "placement"}
    for kind, seen in factors.items():
        assert all(low - 1e-9 <= f <= high + 1e-9 for f in seen), kind
        assert min(seen) < low + 0.3 and max(seen) > high - 0.3, kind  # the whole range drawn
    assert directions == {-2, -1, 0, 1, 9, 11}  # every quadrant, both turns


def test_near_misses_read_the_requests_tolerances(agents) -> None:
    """Under noise the tolerances are widened, and so are the near-misses."""
    exchange = first(agents, "descent")
    wide = exchange.request.tolerances.model_copy(update={"eps_g_m": 0.05, "eps_g_deg": 20.0})
    widened = Exchange(replace(exchange.request, tolerances=wide), exchange.answer)
    answer, _ = corrupt(widened, CorruptionKind.NEAR_OFFSET)
    shift = np.subtract(answer.waypoint.position_m, exchange.answer.waypoint.position_m)  # type: ignore[attr-defined]
    assert 0.05 <= math.hypot(*shift[:2]) <= 0.15
    answer, record = corrupt(widened, CorruptionKind.NEAR_YAW)
    assert "x eps_g_deg 20)" in record.detail


# --- persistence ------------------------------------------------------------------------


def after_refusal(request: AgentRequest, agent: str | None = None, **memory: Any) -> AgentRequest:
    """The next call's request: the memory holds a refusal of ``agent``'s answer (default:
    the stage asked, as the orchestrator names an agent's refusals, and the single
    agent's) and ``memory``'s fields."""
    refusal = Refusal(agent=agent or str(request.memory.step), gate="g", note="refused")
    refusals = (*request.memory.refusals, refusal)
    update = {"refusals": refusals, "last_feedback": refusal.text(), **memory}
    return replace(request, call=request.call + 1, memory=request.memory.model_copy(update=update))


def mistake(record: AnswerCorruption) -> str:
    """What a corruption's detail says changed, its values left out where a repeat may
    recompute them (a wrong choice's group)."""
    if record.kind is CorruptionKind.WRONG_CHOICE:
        return record.detail.rsplit("(", 1)[1]
    return record.detail


def test_at_persistence_1_the_answer_after_each_refusal_repeats_the_mistake(agents, single) -> None:
    kinds = set()
    for exchange in agents + single:
        for kind, seed in ((kind, seed) for kind in ALL for seed in range(2)):
            errors = AnswerErrors(rate=1.0, kinds=(kind,), persistence=1.0)
            reasoner = ImperfectReasoner(Fixed(exchange.answer), errors, seed)
            request = replace(exchange.request, call=0)
            made = reasoner.decide(request).corruption
            if made is None:
                continue
            assert not made.repeated
            for _ in range(3):
                request = after_refusal(request)
                again = reasoner.decide(request).corruption
                assert again is not None and again.repeated, (exchange.step, made.kind)
                assert again.kind is made.kind and mistake(again) == mistake(made)
                assert again.original == made.original
            kinds.add(made.kind)
    assert kinds == set(ALL)


def test_a_repeat_needs_a_refusal_of_the_same_agent_in_the_same_phase_and_brick(agents) -> None:
    errors = AnswerErrors(rate=1.0, persistence=1.0)
    lift = first(agents, "lift")

    def follow_up(exchange: Exchange, *updates: dict[str, Any]) -> bool | None:
        """Whether the answer after the corrupted one, asked with each of ``updates`` in
        turn, repeated its mistake (the last of them)."""
        reasoner = ImperfectReasoner(Fixed(exchange.answer), errors, 1)
        request = replace(exchange.request, call=0)
        assert reasoner.decide(request).corruption is not None
        for update in updates:
            request = replace(request, call=request.call + 1, **update)
            reply = reasoner.decide(request)
        return None if reply.corruption is None else reply.corruption.repeated

    refused = after_refusal(lift.request)
    assert follow_up(lift, {"memory": refused.memory}) is True
    assert follow_up(lift, {"memory": lift.request.memory}) is False  # nothing refused
    other = after_refusal(lift.request, agent="placement")  # another agent was refused
    assert follow_up(lift, {"memory": other.memory}) is False
    placed = (*lift.request.memory.placed, PlacedBrick(brick_id=9, target_index=9))
    moved_on = after_refusal(lift.request, placed=placed)  # a brick was placed since
    assert follow_up(lift, {"memory": moved_on.memory}) is False
    # Ag5: each phase follows up its own mistake.
    carry = first(agents, "placement")
    assert carry.request.memory.phase is PlacementPhase.CARRY
    set_down = after_refusal(carry.request, phase=PlacementPhase.SET_DOWN)
    carry_again = after_refusal(carry.request)
    assert follow_up(carry, {"memory": set_down.memory}) is False
    assert follow_up(carry, {"memory": set_down.memory}, {"memory": carry_again.memory}) is True


def test_persistence_draws_apart_so_that_at_0_every_draw_is_as_without_it(agents) -> None:
    exchange = first(agents, "descent")

    def follow_ups(persistence: float, seed: int) -> list[AgentReply]:
        """The reply after a refusal of each corrupted answer, over 400 calls."""
        errors = AnswerErrors(rate=0.5, persistence=persistence)
        reasoner = ImperfectReasoner(Fixed(exchange.answer), errors, seed)
        found = []
        for call in range(0, 800, 2):
            request = replace(exchange.request, call=call)
            if reasoner.decide(request).corruption is not None:
                found.append(reasoner.decide(after_refusal(request)))
        return found

    fresh = replies(exchange, AnswerErrors(rate=0.5), 3, range(800))  # stateless: by call index
    for persistence in (0.0, 0.5):
        found = follow_ups(persistence, seed=3)
        drawn = [r for r in found if r.corruption is None or not r.corruption.repeated]
        assert all(r in fresh for r in drawn)  # the call's own draw, untouched
        if persistence == 0.0:
            assert len(drawn) == len(found)
        else:
            assert len(drawn) / len(found) == pytest.approx(0.5, abs=0.1)
            assert follow_ups(persistence, seed=3) == found  # seeded


def test_a_mistake_the_next_answer_has_no_room_for_is_not_repeated(agents) -> None:
    lift = first(agents, "lift")
    tools_only = LiftAnswer(tool_calls=[ToolCall(name="slip_estimate", arguments={"brick_id": 0})])
    rng = np.random.default_rng(0)
    assert repeated(tools_only, lift.request, CorruptionKind.SIGN_FLIP, 2, rng) is None

    @dataclass
    class Then:
        """Answers ``answers`` in turn."""

        answers: list[AgentAnswer]
        name: str = "then"

        def decide(self, request: AgentRequest) -> AgentReply:
            return AgentReply(answer=self.answers.pop(0))

    errors = AnswerErrors(rate=1.0, kinds=(CorruptionKind.NEAR_OFFSET,), persistence=1.0)
    reasoner = ImperfectReasoner(Then([lift.answer, tools_only, lift.answer]), errors, 0)
    request = replace(lift.request, call=0)
    assert reasoner.decide(request).corruption is not None
    request = after_refusal(request)
    assert reasoner.decide(request).corruption is None  # no waypoint: nothing to repeat
    again = reasoner.decide(after_refusal(request)).corruption
    assert again is not None and not again.repeated  # drawn anew: no mistake was refused


# --- the draws --------------------------------------------------------------------------


@dataclass
class Fixed:
    """Answers every request with the same answer."""

    answer: AgentAnswer
    name: str = "fixed"

    def decide(self, request: AgentRequest) -> AgentReply:
        return AgentReply(answer=self.answer)


def replies(exchange: Exchange, errors: AnswerErrors, seed: int, calls: range) -> list[AgentReply]:
    reasoner = ImperfectReasoner(Fixed(exchange.answer), errors, seed)
    return [reasoner.decide(replace(exchange.request, call=call)) for call in calls]


def test_the_stream_is_apart_from_the_noise_streams() -> None:
    assert ANSWER_ERROR_STREAM not in (noise.VARIATION_STREAM, noise.PERCEPTION_STREAM)


def test_draws_depend_on_the_trial_seed_and_the_call_index_only(agents) -> None:
    exchange = first(agents, "release")
    errors = AnswerErrors(rate=0.3)
    once = replies(exchange, errors, seed=5, calls=range(2000))
    again = replies(exchange, errors, seed=5, calls=range(2000))
    assert [r.corruption for r in once] == [r.corruption for r in again]
    assert [r.answer for r in once] == [r.answer for r in again]
    corrupted = [r.corruption for r in once if r.corruption is not None]
    assert len(corrupted) / 2000 == pytest.approx(0.3, abs=0.04)
    kinds = {c.kind for c in corrupted}
    assert kinds == {k for k in ALL if applies(exchange, k)}
    other = replies(exchange, errors, seed=6, calls=range(2000))
    assert [r.corruption for r in other] != [r.corruption for r in once]
    # the same call index always draws the same, whatever was asked before it
    assert replies(exchange, errors, seed=5, calls=range(1500, 1501))[0] == once[1500]


def test_rate_0_never_corrupts_and_rate_1_always_does_where_a_kind_applies(agents, single) -> None:
    for exchange in agents + single:
        none = replies(exchange, AnswerErrors(rate=0.0), seed=1, calls=range(20))
        assert all(r.corruption is None and r.answer is exchange.answer for r in none)
        every = replies(exchange, AnswerErrors(rate=1.0), seed=1, calls=range(20))
        applicable = any(applies(exchange, k) for k in ALL)
        assert all((r.corruption is not None) == applicable for r in every), exchange.step


def test_only_the_configured_kinds_are_drawn(agents) -> None:
    exchange = first(agents, "lift")
    errors = AnswerErrors(rate=1.0, kinds=(CorruptionKind.TOO_FAST, CorruptionKind.YAW_180))
    drawn = {r.corruption.kind for r in replies(exchange, errors, 2, range(50))}  # type: ignore[union-attr]
    assert drawn == set(errors.kinds)
    grasp = first(agents, "grasp")
    assert all(r.corruption is None for r in replies(grasp, errors, 2, range(20)))


def test_the_setting_refuses_rates_outside_0_to_1_and_no_kinds() -> None:
    for rate in (-0.1, 1.5, math.nan, math.inf):
        with pytest.raises(ValueError):
            AnswerErrors(rate=rate)
    with pytest.raises(ValueError):
        AnswerErrors(rate=0.5, kinds=())
    for persistence in (-0.1, 1.5, math.nan):
        with pytest.raises(ValueError):
            AnswerErrors(rate=0.5, persistence=persistence)
    # At persistence 0 run.json records the setting as it did before persistence existed.
    assert AnswerErrors().model_dump(mode="json") == {"rate": 0.0, "kinds": [k.value for k in ALL]}
    assert AnswerErrors(persistence=0.5).model_dump(mode="json")["persistence"] == 0.5


def test_kinds_are_named_once_each_in_the_enums_order() -> None:
    assert parse_kinds("all") == ALL
    assert parse_kinds(" near_yaw, sign_flip,near_yaw") == (
        CorruptionKind.SIGN_FLIP,
        CorruptionKind.NEAR_YAW,
    )
    for text, needle in (("sign_flip,bogus", "unknown kind 'bogus'"), ("a,,b", "unknown kind")):
        with pytest.raises(ConfigError, match=needle):
            parse_kinds(text)
    with pytest.raises(ConfigError, match="an empty kind name"):
        parse_kinds("sign_flip,")


# --- in the orchestrator's transcript ---------------------------------------------------


def imperfect_build(kinematics, goal: GoalPattern, rate: float, seed: int = 4) -> BuildResult:
    reasoner = ImperfectReasoner(BuiltinReasoner(), AnswerErrors(rate=rate), trial_seed=seed)
    assert reasoner.name == "builtin"
    return Orchestrator(FakeWorld(goal, BRICKS, *kinematics), reasoner).build(goal)


def test_the_transcript_marks_corrupted_calls_and_keeps_their_originals(kinematics, wall) -> None:
    one = wall.model_copy(update={"targets": wall.targets[:1]})
    result = imperfect_build(kinematics, one, rate=0.3, seed=5)
    corrupted = [c for c in result.transcript if c.corruption is not None]
    assert corrupted and len(corrupted) < len(result.transcript)
    for call in corrupted:
        assert call.corruption.original != call.answer  # type: ignore[union-attr]
        assert call.corruption.detail  # type: ignore[union-attr]
    again = imperfect_build(kinematics, one, rate=0.3, seed=5)
    assert [c.model_dump() for c in again.transcript] == [c.model_dump() for c in result.transcript]
    other = imperfect_build(kinematics, one, rate=0.3, seed=4)
    assert [c.model_dump() for c in other.transcript] != [c.model_dump() for c in result.transcript]


def test_at_rate_1_every_answer_a_kind_applies_to_is_corrupted(kinematics, wall) -> None:
    result = imperfect_build(kinematics, wall, rate=1.0)
    assert result.failure is not None
    assert result.transcript and all(c.corruption is not None for c in result.transcript)
    assert [c.call for c in result.transcript] == list(range(len(result.transcript)))


@dataclass
class Stateless:
    """Answer errors as drawn before persistence existed: each call's own draw."""

    errors: AnswerErrors
    trial_seed: int
    inner: Reasoner = field(default_factory=BuiltinReasoner)
    name: str = "builtin"

    def decide(self, request: AgentRequest) -> AgentReply:
        reply = self.inner.decide(request)
        rng = np.random.default_rng([self.trial_seed, ANSWER_ERROR_STREAM, request.call])
        if rng.random() >= self.errors.rate:
            return reply
        found = corruption(reply.answer, request, self.errors.kinds, rng)
        return reply if found is None else replace(reply, answer=found[0], corruption=found[1])


def test_at_persistence_0_a_build_draws_as_it_did_without_persistence(kinematics, wall) -> None:
    errors = AnswerErrors(rate=0.3)
    for runner, seed in ((Orchestrator, 4), (Orchestrator, 1), (single_agent, 2)):
        built = [
            runner(FakeWorld(wall, BRICKS, *kinematics), reasoner).build(wall).transcript
            for reasoner in (
                ImperfectReasoner(BuiltinReasoner(), errors, seed),
                Stateless(errors, seed),
            )
        ]
        assert [c.model_dump() for c in built[0]] == [c.model_dump() for c in built[1]]
        assert not any(c.corruption.repeated for c in built[0] if c.corruption)


def test_at_persistence_1_a_build_repeats_each_refused_mistake(kinematics, wall) -> None:
    errors = AnswerErrors(rate=0.3, persistence=1.0)
    repeats = 0
    for seed in range(4):
        reasoner = ImperfectReasoner(BuiltinReasoner(), errors, trial_seed=seed)
        transcript = (
            Orchestrator(FakeWorld(wall, BRICKS, *kinematics), reasoner).build(wall).transcript
        )
        for index, call in enumerate(transcript):
            before = [c for c in transcript[:index] if c.agent == call.agent]
            if not before or before[-1].corruption is None:
                continue
            earlier = before[-1]
            if earlier.outcome in (Outcome.REFUSED, Outcome.RAISED, Outcome.REGRASP):
                assert call.corruption is not None and call.corruption.repeated, (seed, index)
                assert call.corruption.kind is earlier.corruption.kind  # type: ignore[union-attr]
                repeats += 1
            else:  # the mistake ran: nothing to repeat
                assert call.corruption is None or not call.corruption.repeated
    assert repeats >= 4


# --- what caught them: results lines ----------------------------------------------------


def gate(name: str, *checks: tuple[str, bool]) -> GateRecord:
    records = [
        CheckRecord(name=c, value=0.0, relation="<=", threshold=1.0, passed=ok) for c, ok in checks
    ]
    passed = all(ok for _, ok in checks)
    return GateRecord(gate=name, passed=passed, checks=records, after_move=judged_after_move(name))


def test_a_corrupted_answer_is_counted_by_what_caught_it() -> None:
    """(tests/test_error_catches.py classifies each case; here they are counted.)"""
    flip, hover = CorruptionKind.SIGN_FLIP, CorruptionKind.SKIPPED_HOVER
    corrupted = AnswerCorruption(kind=flip, detail="x", original={})
    call = AgentCall(
        call=0, agent="lift", brick=0, target=0, attempt=1, prompt_chars=1, answer={},
        corruption=corrupted,
    )  # fmt: skip
    sigma4 = gate("sigma4_lift", ("normal_force_n", True), ("slip_mps", False), ("tilt", False))
    sigma5 = gate("sigma5_placement", ("e_xy_m", False))
    cases = [
        ({"outcome": Outcome.REGRASP, "gates": [gate("lift_plan", ("c", True)), sigma4]},
         "sigma4_lift:slip_mps"),
        ({"outcome": Outcome.RAISED, "gates": [gate("a", ("x", False)), sigma5]},
         "sigma5_placement:e_xy_m"),
        ({"outcome": Outcome.REFUSED, "gates": [gate("lift_answer", ("valid_answer", False))]},
         "lift_answer:valid_answer"),
        ({"outcome": Outcome.REFUSED}, "refused"),
        ({"outcome": Outcome.ACCEPTED, "gates": [gate("a", ("x", True))]}, "missed"),
        ({"outcome": Outcome.EXECUTED}, "missed"),
        ({"outcome": Outcome.PENDING}, "trial_stopped"),
        ({"outcome": Outcome.FAILED}, "trial_stopped"),
    ]  # fmt: skip
    for update, caught in cases:
        assert call.model_copy(update=update).caught_by == caught
    calls = [call.model_copy(update=update) for update, _ in cases]
    calls[1] = calls[1].model_copy(
        update={"corruption": corrupted.model_copy(update={"kind": hover, "repeated": True})}
    )
    calls.append(call.model_copy(update={"corruption": None}))
    counts = AnswerErrorCounts.of(calls)
    assert counts.corrupted == len(cases)
    assert counts.by_kind == {flip: len(cases) - 1, hover: 1}
    assert counts.repeated == {hover: 1}
    assert counts.caught_by == {
        "lift_answer:valid_answer": 1, "missed": 2, "refused": 1, "sigma4_lift:slip_mps": 1,
        "sigma5_placement:e_xy_m": 1, "trial_stopped": 2,
    }  # fmt: skip
    assert counts.caught == {
        flip: {Caught.BEFORE: 2, Caught.AFTER: 1, Caught.MISSED: 2, Caught.TRIAL_STOPPED: 2},
        hover: {Caught.AFTER: 1},
    }
    assert counts.checks == {
        "lift_answer:valid_answer": {flip: 1},
        "refused": {flip: 1},
        "sigma4_lift:slip_mps": {flip: 1},
        "sigma5_placement:e_xy_m": {hover: 1},
    }
    assert counts.led_to == {flip: {"harmless": 2}}  # no brick placed, no failure
    assert counts.would_catch == {}
    double = counts + counts
    assert double.corrupted == 16 and double.by_kind == {flip: 14, hover: 2}
    assert double.caught[flip] == {k: 2 * n for k, n in counts.caught[flip].items()}
    assert double.checks["sigma5_placement:e_xy_m"] == {hover: 2}
    assert double.repeated == {hover: 2} and double.led_to == {flip: {"harmless": 4}}
    stored = json.loads(counts.model_dump_json())
    assert "would_catch" not in stored and stored["caught"]["skipped_hover"] == {"after": 1}


def test_a_build_counts_every_corrupted_answer_once(kinematics, wall) -> None:
    result = imperfect_build(kinematics, wall, rate=0.3)
    counts = AnswerErrorCounts.of(result.transcript, result.failure)
    assert counts.corrupted == sum(c.corruption is not None for c in result.transcript) > 2
    assert sum(counts.by_kind.values()) == sum(counts.caught_by.values()) == counts.corrupted
    assert sum(n for row in counts.caught.values() for n in row.values()) == counts.corrupted
    caught = sum(counts.caught[k].get(w, 0) for k in counts.caught for w in ("before", "after"))
    assert sum(n for row in counts.checks.values() for n in row.values()) == caught > 0
    missed = sum(row.get(Caught.MISSED, 0) for row in counts.caught.values())
    assert sum(n for row in counts.led_to.values() for n in row.values()) == missed


def line(counts: AnswerErrorCounts | None = None, trial: int = 0) -> TrialResult:
    """A results line of no bricks, with ``counts``."""
    metrics = PlacementMetrics(
        center_offset_cm=0.0, rotation_error_deg=0.0, symmetric_rotation_error_deg=0.0, iou=1.0
    )
    return TrialResult(
        method="agents", pattern="p", seed=0, trial=trial, trial_seed=1, success=True,
        llm="builtin", bricks=(), bricks_placed=0, metrics=metrics, failure=None, sim_steps=0,
        answer_errors=counts,
    )  # fmt: skip


def test_lines_at_rate_0_have_no_answer_errors_field_and_the_schema_has_one() -> None:
    assert "answer_errors" not in json.loads(line().model_dump_json())
    counted = line(AnswerErrorCounts())
    stored = json.loads(counted.model_dump_json())["answer_errors"]
    assert stored == {"corrupted": 0, "by_kind": {}, "caught_by": {}}
    assert TrialResult.model_validate_json(counted.model_dump_json()) == counted
    printed = cli("schema", "results")
    assert printed.returncode == 0 and "AnswerErrorCounts" in printed.stdout


def test_summaries_sum_the_counts_and_name_the_rate() -> None:
    """Counts as lines written before ``caught`` hold them: summary.md shows ``caught_by``
    (tests/test_error_catches.py: today's)."""
    flip, hover = CorruptionKind.SIGN_FLIP, CorruptionKind.SKIPPED_HOVER
    results = [
        line(AnswerErrorCounts(corrupted=2, by_kind={flip: 2}, caught_by={"g:c": 1, "missed": 1})),
        line(AnswerErrorCounts(corrupted=1, by_kind={hover: 1}, caught_by={"g:c": 1}), trial=1),
    ]
    errors = AnswerErrors(rate=0.25)
    summary = summarize(results, 1.0, answer_errors=errors)
    assert summary.answer_errors is not None
    assert summary.answer_errors.model_dump(mode="json") == {
        "corrupted": 3,
        "by_kind": {"sign_flip": 2, "skipped_hover": 1},
        "caught_by": {"g:c": 2, "missed": 1},
        "rate": 0.25,
        "kinds": [k.value for k in ALL],
    }
    markdown = summary_markdown(summary)
    assert markdown.splitlines()[0].endswith(", answer errors 0.25")
    assert f"| `sign_flip` | {flip.meaning} | 2 |" in markdown
    assert "| `g:c` | 2 |" in markdown and "| `missed` | 1 |" in markdown
    for at_zero in (summarize(results, 1.0), summarize(results, 1.0, answer_errors=AnswerErrors())):
        assert at_zero.answer_errors is None
        assert "answer_errors" not in json.loads(at_zero.model_dump_json())
        assert "Answer errors" not in summary_markdown(at_zero)


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--answer-errors", "1.5"), "--answer-errors 1.5"),
        (("--answer-errors", "-0.2"), "--answer-errors -0.2"),
        (("--answer-errors", "nan"), "--answer-errors nan"),
        (("--answer-errors", "inf"), "--answer-errors inf"),
        (("--method", "classical", "--answer-errors", "0.1"), "drop --answer-errors"),
        (("--answer-errors", "0.1", "--answer-error-persistence", "2"),
         "--answer-error-persistence 2.0: give a probability from 0 to 1"),
        (("--answer-errors", "0.1", "--answer-error-persistence", "nan"),
         "--answer-error-persistence nan"),
        (("--answer-errors", "0.1", "--answer-error-kinds", "near_yaw,bogus"),
         "unknown kind 'bogus'"),
        (("--answer-errors", "0.1", "--answer-error-kinds", ""), "an empty kind name"),
        (("--answer-error-persistence", "0.5",), "drop --answer-error-persistence"),
        (("--answer-error-kinds", "near_yaw",), "drop --answer-error-kinds"),
    ],
)  # fmt: skip
def test_bad_answer_error_rates_are_refused_in_one_line(
    tmp_path: Path, args: tuple[str, ...], needle: str
) -> None:
    result = cli("eval", *args, "--trials", "1", "--out", str(tmp_path / "o"))
    assert_clean_error(result, needle)
    assert not (tmp_path / "o").exists()


def test_the_docs_table_is_the_enum_in_order() -> None:
    page = "agents-and-gates.md"
    rows = doc_table(page, "## Answer errors", "| kind | what changes | where it applies |")
    assert rows == [(k.value, k.meaning, k.applies_to) for k in ALL]
    assert "Which check catches each kind, before the arm moves" in (DOCS / page).read_text()


def test_the_single_agents_corrupted_answers_are_marked_and_counted(kinematics, wall) -> None:
    def build(seed: int) -> BuildResult:
        reasoner = ImperfectReasoner(BuiltinReasoner(), AnswerErrors(rate=0.3), trial_seed=seed)
        return single_agent(FakeWorld(wall, BRICKS, *kinematics), reasoner).build(wall)

    result = build(seed=2)
    corrupted = [c for c in result.transcript if c.corruption is not None]
    assert corrupted and all(c.corruption.original != c.answer for c in corrupted)  # type: ignore[union-attr]
    counts = AnswerErrorCounts.of(result.transcript)
    # Nothing gates it: what is caught, validation caught (its answers' data, or the reach).
    caught = {key.split(":")[0] for key in counts.caught_by} - {"missed", "trial_stopped"}
    assert all(gate.endswith("_answer") or gate == "controller" for gate in caught)
    assert [c.model_dump() for c in build(seed=2).transcript] == [
        c.model_dump() for c in result.transcript
    ]


# --- real trials ------------------------------------------------------------------------

TWO_BRICKS = {**SMALL_PATTERN, "name": "two", "bricks": SMALL_PATTERN["bricks"][:2]}


@pytest.mark.slow
def test_eval_with_answer_errors_is_the_same_run_to_run_and_resumed(tmp_path: Path) -> None:
    pattern = tmp_path / "two.json"
    pattern.write_text(json.dumps(TWO_BRICKS))

    def run(out: str, trials: int, rate: str = "0.2") -> subprocess.CompletedProcess[str]:
        return cli(
            "eval", "--method", "agents", "--pattern", str(pattern), "--trials", str(trials),
            "--answer-errors", rate, "--seed", "3", "--workers", "1", "--transcripts",
            "--out", str(tmp_path / out),
        )  # fmt: skip

    def lines(out: str) -> str:
        return (tmp_path / out / "results.jsonl").read_text()

    for out in ("a", "b"):
        assert run(out, 2).returncode == 0
    assert lines("a") == lines("b")
    assert run("c", 1).returncode == 0
    assert run("c", 2).returncode == 0
    assert lines("c") == lines("a")
    records = [TrialResult.model_validate_json(line) for line in lines("a").splitlines()]
    counts = [r.answer_errors for r in records]
    assert sum(c.corrupted for c in counts if c is not None) > 0
    for trial, record in enumerate(records):
        calls = [
            AgentCall.model_validate_json(text)
            for text in (tmp_path / "a" / "transcripts" / f"trial_{trial:03d}.jsonl")
            .read_text()
            .splitlines()
        ]
        misplaced = {b.id for b in record.bricks if not SuccessRule().is_placed(b)}
        assert AnswerErrorCounts.of(calls, record.failure, misplaced) == record.answer_errors
        assert premove_refusals(calls) == record.premove_refusals
    stored = json.loads((tmp_path / "a" / "run.json").read_text())["config"]["answer_errors"]
    assert stored == {"rate": 0.2, "kinds": [k.value for k in ALL]}
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())["answer_errors"]
    assert summary["corrupted"] == sum(c.corrupted for c in counts) and summary["rate"] == 0.2
    refused = run("a", 2, rate="0.1")
    assert_clean_error(refused, "answer_errors.rate 0.2 there, 0.1 now")
    assert lines("a") == lines("b")
    shown = cli("report", str(tmp_path / "a"), "--out", str(tmp_path / "report"))
    assert shown.returncode == 0, shown.stderr
    table = (tmp_path / "report" / "table.md").read_text()
    assert "| agents (builtin, tools check), paper, answer errors 0.2 | two | 0.2 |" in table
    assert 'id="answer-errors"' in (tmp_path / "report" / "report.html").read_text()


def test_at_persistence_1_the_single_agents_refused_mistake_is_repeated(kinematics, wall) -> None:
    """The single agent's refusals name the stage it answered, as an agent's do: its next
    answer at that stage repeats the mistake."""
    errors = AnswerErrors(rate=0.3, persistence=1.0)
    repeats = 0
    for seed in range(4):
        reasoner = ImperfectReasoner(BuiltinReasoner(), errors, trial_seed=seed)
        transcript = single_agent(FakeWorld(wall, BRICKS, *kinematics), reasoner).build(wall)
        for earlier, call in itertools.pairwise(transcript.transcript):
            if earlier.corruption is not None and earlier.outcome == "refused":
                assert call.corruption is not None and call.corruption.repeated
                assert call.corruption.kind == earlier.corruption.kind
                repeats += 1
    assert repeats
