"""The imperfect reasoner: any reasoner's answers, corrupted the way language models err.

``eval --answer-errors RATE`` wraps whatever reasoner runs (built-in, LLM, replay, an
outside agent) in :class:`ImperfectReasoner`. Each answer is corrupted with probability
RATE by one kind of mistake (:class:`~actionreasoning.agents.answer_errors.CorruptionKind`),
drawn uniformly among the configured kinds that apply to it; an answer none applies to (a
tool-only answer, the single agent's ``done``) is left as it is. The draws come from the
trial's seed and the call's index alone, so the same trial is corrupted the same way, and a
retry (a new call) draws anew. A corrupted answer is built in the agent's answer model
(whose decision fields may be left out, where a decision's may not) with ``model_copy`` (no
validation), so it may be invalid: the orchestrator's checks must catch it.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from actionreasoning.agents.answer_errors import AnswerCorruption, AnswerErrors, CorruptionKind
from actionreasoning.agents.outputs import (
    AgentAnswer,
    GraspAnswer,
    PreGraspAnswer,
    SingleAgentAnswer,
    WaypointProposal,
)
from actionreasoning.agents.reasoner import AgentReply, AgentRequest, Reasoner
from actionreasoning.agents.view import target_supports
from actionreasoning.world.geometry import QuatXYZW, Vec3, as_vec3
from actionreasoning.world.models import BrickStatus
from actionreasoning.world.stages import Stage

#: The stream of a trial's seed that answer errors draw from (world/noise.py has 1 and 2).
ANSWER_ERROR_STREAM = 3
#: A displacement component smaller than this (m) counts as no move.
MIN_MOVE_M = 0.001
#: cm_as_m: a length in centimetres written as metres.
CM_AS_M_FACTOR = 100.0
#: The decision fields missing_field may leave out (set to None), in this order.
DECISION_FIELDS = ("waypoint", "gripper_opening_m", "brick_id", "target_index")

#: One way to corrupt an answer: the fields to replace and a line saying what changed.
Change = tuple[dict[str, Any], str]
#: The changes a kind can make to an answer, in groups: a group is drawn, then a change in
#: it (each uniformly). No group: the kind does not apply.
Choices = list[list[Change]]


class ImperfectReasoner:
    """``inner``'s answers, each corrupted with probability ``errors.rate`` (see the module)."""

    def __init__(self, inner: Reasoner, errors: AnswerErrors, trial_seed: int) -> None:
        self.inner = inner
        self.errors = errors
        self.trial_seed = trial_seed
        self.name = inner.name

    def decide(self, request: AgentRequest) -> AgentReply:
        """The inner reasoner's reply, its answer corrupted if this call's draw says so."""
        reply = self.inner.decide(request)
        rng = np.random.default_rng([self.trial_seed, ANSWER_ERROR_STREAM, request.call])
        if rng.random() >= self.errors.rate:
            return reply
        found = corruption(reply.answer, request, self.errors.kinds, rng)
        if found is None:
            return reply
        answer, corrupted = found
        return replace(reply, answer=answer, corruption=corrupted)


def corruption(
    answer: AgentAnswer,
    request: AgentRequest,
    kinds: Sequence[CorruptionKind],
    rng: np.random.Generator,
) -> tuple[AgentAnswer, AnswerCorruption] | None:
    """``answer`` corrupted by one of ``kinds``, drawn among those that apply to it, and
    the record of it; None if none applies."""
    if isinstance(answer, SingleAgentAnswer) and answer.step == "done":
        return None
    applicable = {kind: choices for kind in kinds if (choices := CHOICES[kind](answer, request))}
    if not applicable:
        return None
    kind = list(applicable)[rng.integers(len(applicable))]
    groups = applicable[kind]
    group = groups[rng.integers(len(groups))]
    update, detail = group[rng.integers(len(group))]
    original = answer.model_dump(mode="json")
    corrupted = AnswerCorruption(kind=kind, detail=detail, original=original)
    return request.spec.output_model.of(answer).model_copy(update=update), corrupted


# --- the kinds: what each can change in an answer -------------------------------------


def _sign_flip(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint, moved = _displacement(answer, request)
    if waypoint is None:
        return []
    axes = [axis for axis in (0, 1) if abs(moved[axis]) >= MIN_MOVE_M]
    if not axes and abs(moved[2]) >= MIN_MOVE_M:
        axes = [2]
    return [[_moved_axis(waypoint, request, axis, -moved[axis])] for axis in axes]


def _cm_as_m(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint, moved = _displacement(answer, request)
    if waypoint is None:
        return []
    axis = max(range(3), key=lambda i: abs(moved[i]))
    scaled = moved[axis] * CM_AS_M_FACTOR
    if abs(moved[axis]) < MIN_MOVE_M or not math.isfinite(scaled):
        return []
    return [[_moved_axis(waypoint, request, axis, scaled)]]


def _yaw(turns_deg: Sequence[float]) -> Callable[[AgentAnswer, AgentRequest], Choices]:
    def choices(answer: AgentAnswer, request: AgentRequest) -> Choices:
        waypoint = _waypoint(answer)
        if waypoint is None:
            return []
        return [[_turned(waypoint, turn)] for turn in turns_deg]

    return choices


def _into_obstacle(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint = _waypoint(answer)
    if waypoint is None:
        return []
    placed = [b for b in request.state.bricks if b.status == BrickStatus.PLACED]
    if placed:
        return [
            [_moved_to(waypoint, b.pose.position_m, f"the centre of placed brick {b.id}")]
            for b in placed
        ]
    x, y, _ = waypoint.position_m
    return [[_moved_to(waypoint, (x, y, 0.0), "into the ground")]]


def _skipped_hover(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint = _waypoint(answer)
    if waypoint is None:
        return []
    step = answer.step if isinstance(answer, SingleAgentAnswer) else request.spec.key
    picked = _choice(answer)
    if step == Stage.PRE_GRASP and picked is not None:
        if picked.brick_id not in {b.id for b in request.state.bricks}:
            return []
        goal = request.state.brick(picked.brick_id).pose.position_m[2]
        what = f"the centre of brick {picked.brick_id}"
    elif step == Stage.TRANSFER and request.memory.current_target is not None:
        targets = {t.index: t for t in request.state.goal.targets}
        target = targets.get(request.memory.current_target)
        if target is None:
            return []
        goal, what = target.pose.position_m[2], f"the centre of target {target.index}"
    else:
        return []
    x, y, z = waypoint.position_m
    if z - goal < MIN_MOVE_M:
        return []
    return [[_moved_to(waypoint, (x, y, goal), what)]]


def _too_fast(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint = _waypoint(answer)
    if waypoint is None or waypoint.duration_s is None:
        return []
    update = {"waypoint": waypoint.model_copy(update={"duration_s": None})}
    return [[(update, f"waypoint.duration_s {waypoint.duration_s:.3f} -> None")]]


def _wrong_choice(answer: AgentAnswer, request: AgentRequest) -> Choices:
    picked = _choice(answer)
    if picked is None or picked.brick_id is None or picked.target_index is None:
        return []
    state, memory = request.state, request.memory
    brick, target = picked.brick_id, picked.target_index
    built = {p.target_index for p in memory.placed}
    supports = target_supports(state.goal)
    unsupported = [
        t.index
        for t in state.goal.targets
        if t.index not in built and t.index != target and not set(supports[t.index]) <= built
    ]
    groups = [
        [
            ({"brick_id": b.id}, f"brick_id {brick} -> {b.id} (placed)")
            for b in state.bricks
            if b.status == BrickStatus.PLACED and b.id != brick
        ],
        [({"target_index": t}, f"target_index {target} -> {t} (built)") for t in sorted(built)],
        [
            ({"target_index": t}, f"target_index {target} -> {t} (its support is not built)")
            for t in unsupported
        ],
    ]
    groups = [group for group in groups if group]
    if groups:
        return groups
    beyond = max(b.id for b in state.bricks) + 1 if state.bricks else 0
    return [[({"brick_id": beyond}, f"brick_id {brick} -> {beyond} (no such brick)")]]


def _missing_field(answer: AgentAnswer, request: AgentRequest) -> Choices:
    changes: list[Change] = [
        ({name: None}, f"{name} -> None")
        for name in DECISION_FIELDS
        if getattr(answer, name, None) is not None
    ]
    if isinstance(answer, GraspAnswer | SingleAgentAnswer) and answer.close:
        changes.append(({"close": False}, "close True -> False"))
    return [[change] for change in changes]


CHOICES: dict[CorruptionKind, Callable[[AgentAnswer, AgentRequest], Choices]] = {
    CorruptionKind.SIGN_FLIP: _sign_flip,
    CorruptionKind.YAW_90: _yaw((90.0, -90.0)),
    CorruptionKind.YAW_180: _yaw((180.0,)),
    CorruptionKind.CM_AS_M: _cm_as_m,
    CorruptionKind.INTO_OBSTACLE: _into_obstacle,
    CorruptionKind.SKIPPED_HOVER: _skipped_hover,
    CorruptionKind.TOO_FAST: _too_fast,
    CorruptionKind.WRONG_CHOICE: _wrong_choice,
    CorruptionKind.MISSING_FIELD: _missing_field,
}


# --- helpers ----------------------------------------------------------------------------


def _waypoint(answer: AgentAnswer) -> WaypointProposal | None:
    waypoint = getattr(answer, "waypoint", None)
    return waypoint if isinstance(waypoint, WaypointProposal) else None


def _displacement(
    answer: AgentAnswer, request: AgentRequest
) -> tuple[WaypointProposal | None, Vec3]:
    """The answer's waypoint and its displacement from the tool's position now."""
    waypoint = _waypoint(answer)
    if waypoint is None:
        return None, (0.0, 0.0, 0.0)
    tool = request.state.robot.ee_pose.position_m
    return waypoint, as_vec3(np.subtract(waypoint.position_m, tool))


def _choice(answer: AgentAnswer) -> PreGraspAnswer | SingleAgentAnswer | None:
    """The answer if it is one that picks a brick and a target: Ag1's, or the single
    agent's pre_grasp."""
    if isinstance(answer, SingleAgentAnswer):
        return answer if answer.step == Stage.PRE_GRASP else None
    return answer if isinstance(answer, PreGraspAnswer) else None


def _moved_axis(
    waypoint: WaypointProposal, request: AgentRequest, axis: int, displacement: float
) -> Change:
    """The waypoint with its ``axis`` component at ``displacement`` from the tool's."""
    position = list(waypoint.position_m)
    position[axis] = request.state.robot.ee_pose.position_m[axis] + displacement
    update = {"waypoint": waypoint.model_copy(update={"position_m": tuple(position)})}
    old, new = waypoint.position_m[axis], position[axis]
    return update, f"waypoint.position_m[{axis}] {old:.3f} -> {new:.3f}"


def _moved_to(waypoint: WaypointProposal, position: Vec3, what: str) -> Change:
    update = {"waypoint": waypoint.model_copy(update={"position_m": tuple(position)})}
    old = _short(waypoint.position_m)
    return update, f"waypoint.position_m {old} -> {_short(position)} ({what})"


def _turned(waypoint: WaypointProposal, turn_deg: float) -> Change:
    """The waypoint's orientation turned by ``turn_deg`` about world z: R' = Rz(turn) R."""
    quat = yaw_turned(waypoint.quat_xyzw, math.radians(turn_deg))
    update = {"waypoint": waypoint.model_copy(update={"quat_xyzw": quat})}
    return update, (
        f"waypoint.quat_xyzw {_short(waypoint.quat_xyzw)} -> {_short(quat)} "
        f"(turned {turn_deg:+g} deg about world z)"
    )


def yaw_turned(quat_xyzw: QuatXYZW, angle_rad: float) -> QuatXYZW:
    """The quaternion of Rz(angle) * R, for R given by ``quat_xyzw`` (left as it is scaled:
    no normalisation)."""
    x, y, z, w = quat_xyzw
    c, s = math.cos(angle_rad / 2.0), math.sin(angle_rad / 2.0)
    return (c * x - s * y, c * y + s * x, c * z + s * w, c * w - s * z)


def _short(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"
