"""The imperfect reasoner: any reasoner's answers, corrupted the way language models err.

``eval --answer-errors RATE`` wraps whatever reasoner runs (built-in, LLM, replay, an
outside agent) in :class:`ImperfectReasoner`. Each answer is corrupted with probability
RATE by one kind of mistake (:class:`~actionreasoning.agents.answer_errors.CorruptionKind`),
drawn uniformly among the configured kinds that apply to it; an answer none applies to (a
tool-only answer) is left as it is. The draws come from the
trial's seed and the call's index alone, so the same trial is corrupted the same way, and a
retry (a new call) draws anew. A corrupted answer is built in the agent's answer model
(whose decision fields may be left out, where a decision's may not) with ``model_copy`` (no
validation), so it may be invalid: the orchestrator's checks must catch it.

Persistence (``AnswerErrors.persistence`` P): language models hold misconceptions, so a
mistake can outlive its refusal. With probability P the answer that follows the refusal of a
corrupted answer repeats its mistake: the same kind on the same field (the same axis, turn,
field, group of wrong choices, or the near-miss's direction and factor), recomputed on the
new answer. It follows the refusal when it is the next request to the same agent (for Ag5,
in the same phase) on the same brick, and the task memory holds a refusal of that agent's
since the corrupted answer (refused, raised by sigma_5 or put down by sigma_4). The repeat
draws from a stream of its own (``[trial_seed, 3, call, 1]``), so at P = 0 every draw is as
without persistence; a mistake that the new answer gives no room for (no waypoint, no move
along that axis) is not repeated, and the call draws as any other.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from actionreasoning.agents.answer_errors import (
    GUARDING_TOLERANCES,
    NEAR_MISS_FACTORS,
    AnswerCorruption,
    AnswerErrors,
    CorruptionKind,
)
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
#: The sub-stream of a call that its persistent repeat draws from.
REPEAT_STREAM = 1
#: A displacement component smaller than this (m) counts as no move.
MIN_MOVE_M = 0.001
#: cm_as_m: a length in centimetres written as metres.
CM_AS_M_FACTOR = 100.0
#: The decision fields missing_field may leave out (set to None), in this order.
DECISION_FIELDS = ("waypoint", "gripper_opening_m", "brick_id", "target_index")


@dataclass(frozen=True)
class Change:
    """One way to corrupt an answer: the fields to replace, a line saying what changed, and
    which mistake it is (``mark``: the axis, turn, field, group or near-miss; a repeat makes
    the change of the same mark on the next answer)."""

    update: dict[str, Any]
    detail: str
    mark: Hashable


#: The changes a kind can make to an answer, in groups: a group is drawn, then a change in
#: it (each uniformly). No group: the kind does not apply.
Choices = list[list[Change]]


@dataclass(frozen=True)
class Near:
    """A near-miss: off by ``factor`` times its tolerance, in ``direction`` (near_offset: the
    horizontal direction, radians from world x; near_yaw: +1 or -1)."""

    direction: float
    factor: float


@dataclass(frozen=True)
class Mistake:
    """A corrupted answer that a later answer may repeat: its kind and mark, and the task
    memory's refusal count and bricks placed when it was made."""

    kind: CorruptionKind
    mark: Hashable
    refusals: int
    placed: int


class ImperfectReasoner:
    """``inner``'s answers, each corrupted with probability ``errors.rate``, a refused
    mistake repeated with probability ``errors.persistence`` (see the module). It keeps the
    mistakes of one trial: make one per trial."""

    def __init__(self, inner: Reasoner, errors: AnswerErrors, trial_seed: int) -> None:
        self.inner = inner
        self.errors = errors
        self.trial_seed = trial_seed
        self.name = inner.name
        #: The last corrupted answer at each stage (and Ag5 phase) not yet followed up.
        self._mistakes: dict[tuple[str, str | None], Mistake] = {}

    def decide(self, request: AgentRequest) -> AgentReply:
        """The inner reasoner's reply, its answer corrupted if this call's draws say so."""
        reply = self.inner.decide(request)
        # The stage asked: an agent's own, or the one the single agent answers now.
        slot = (str(request.memory.step), request.memory.phase)
        earlier = self._mistakes.pop(slot, None)
        found = None
        if (
            earlier is not None
            and self.errors.persistence > 0
            and follows_refusal(earlier, request)
        ):
            rng = np.random.default_rng(
                [self.trial_seed, ANSWER_ERROR_STREAM, request.call, REPEAT_STREAM]
            )
            if rng.random() < self.errors.persistence:
                found = repeated(reply.answer, request, earlier.kind, earlier.mark, rng)
        if found is None:
            rng = np.random.default_rng([self.trial_seed, ANSWER_ERROR_STREAM, request.call])
            if rng.random() >= self.errors.rate:
                return reply
            found = _corrupted(reply.answer, request, self.errors.kinds, rng)
        if found is None:
            return reply
        answer, corrupted, mark = found
        memory = request.memory
        self._mistakes[slot] = Mistake(
            corrupted.kind, mark, len(memory.refusals), len(memory.placed)
        )
        return replace(reply, answer=answer, corruption=corrupted)


def follows_refusal(mistake: Mistake, request: AgentRequest) -> bool:
    """Whether ``request`` (the next to the agent that made ``mistake``) follows a refusal
    of it: the same brick is being built, and the memory holds a refusal of this agent's
    made since (refused, raised or put down)."""
    memory, key = request.memory, str(request.memory.step)
    if len(memory.placed) != mistake.placed or len(memory.refusals) <= mistake.refusals:
        return False
    return any(refusal.agent == key for refusal in memory.refusals[mistake.refusals :])


def corruption(
    answer: AgentAnswer,
    request: AgentRequest,
    kinds: Sequence[CorruptionKind],
    rng: np.random.Generator,
) -> tuple[AgentAnswer, AnswerCorruption] | None:
    """``answer`` corrupted by one of ``kinds``, drawn among those that apply to it, and
    the record of it; None if none applies."""
    found = _corrupted(answer, request, kinds, rng)
    return None if found is None else found[:2]


def repeated(
    answer: AgentAnswer,
    request: AgentRequest,
    kind: CorruptionKind,
    mark: Hashable,
    rng: np.random.Generator,
) -> tuple[AgentAnswer, AnswerCorruption, Hashable] | None:
    """``answer`` with the mistake ``kind``/``mark`` made again (a change of that mark drawn
    uniformly, where a group holds several), its record (``repeated``) and the mark; None if
    the answer gives no room for it."""
    if kind in NEAR_CHANGES:
        assert isinstance(mark, Near)
        change = NEAR_CHANGES[kind](answer, request, mark)
        changes = [] if change is None else [change]
    else:
        groups = REPEATS.get(kind, CHOICES[kind])(answer, request)
        changes = [change for group in groups for change in group if change.mark == mark]
    if not changes:
        return None
    return _made(answer, request, kind, changes[rng.integers(len(changes))], repeated=True)


def _corrupted(
    answer: AgentAnswer,
    request: AgentRequest,
    kinds: Sequence[CorruptionKind],
    rng: np.random.Generator,
) -> tuple[AgentAnswer, AnswerCorruption, Hashable] | None:
    """:func:`corruption` with the mistake's mark. The near-misses draw their direction and
    factor after the kind, so that the other kinds draw as they did before near-misses."""
    applicable: dict[CorruptionKind, Choices] = {}
    for kind in kinds:
        if kind in NEAR_CHANGES:
            position, yaw = _guard(answer, request)
            if (position if kind is CorruptionKind.NEAR_OFFSET else yaw) is not None:
                applicable[kind] = []
        elif choices := CHOICES[kind](answer, request):
            applicable[kind] = choices
    if not applicable:
        return None
    kind = list(applicable)[rng.integers(len(applicable))]
    if kind in NEAR_CHANGES:
        factor = float(rng.uniform(*NEAR_MISS_FACTORS))
        if kind is CorruptionKind.NEAR_OFFSET:
            direction = float(rng.uniform(0.0, 2.0 * math.pi))
        else:
            direction = float(rng.choice((1.0, -1.0)))
        change = NEAR_CHANGES[kind](answer, request, Near(direction, factor))
        assert change is not None  # _guard said it applies
    else:
        groups = applicable[kind]
        group = groups[rng.integers(len(groups))]
        change = group[rng.integers(len(group))]
    return _made(answer, request, kind, change)


def _made(
    answer: AgentAnswer,
    request: AgentRequest,
    kind: CorruptionKind,
    change: Change,
    repeated: bool = False,
) -> tuple[AgentAnswer, AnswerCorruption, Hashable]:
    """The answer changed by ``change`` (in the agent's answer model, unvalidated), its
    record and the change's mark."""
    original = answer.model_dump(mode="json")
    corrupted = AnswerCorruption(
        kind=kind, detail=change.detail, original=original, repeated=repeated
    )
    made = request.spec.output_model.of(answer).model_copy(update=change.update)
    return made, corrupted, change.mark


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
    """The largest component times 100."""
    _, moved = _displacement(answer, request)
    return _scaled(answer, request, max(range(3), key=lambda i: abs(moved[i])))


def _cm_as_m_again(answer: AgentAnswer, request: AgentRequest) -> Choices:
    """A repeat: any component that moves times 100 (the one repeated need not be the
    largest of the new answer)."""
    return [group for axis in range(3) for group in _scaled(answer, request, axis)]


def _scaled(answer: AgentAnswer, request: AgentRequest, axis: int) -> Choices:
    waypoint, moved = _displacement(answer, request)
    if waypoint is None:
        return []
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
            [_moved_to(waypoint, b.pose.position_m, f"the centre of placed brick {b.id}", b.id)]
            for b in placed
        ]
    x, y, _ = waypoint.position_m
    return [[_moved_to(waypoint, (x, y, 0.0), "into the ground", "ground")]]


def _skipped_hover(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint = _waypoint(answer)
    if waypoint is None:
        return []
    picked = _choice(answer)
    if _step(answer, request) != Stage.PRE_GRASP or picked is None:
        return []
    if picked.brick_id not in {b.id for b in request.state.bricks}:
        return []
    goal = request.state.brick(picked.brick_id).pose.position_m[2]
    what = f"the centre of brick {picked.brick_id}"
    x, y, z = waypoint.position_m
    if z - goal < MIN_MOVE_M:
        return []
    return [[_moved_to(waypoint, (x, y, goal), what, "hover")]]


def _too_fast(answer: AgentAnswer, request: AgentRequest) -> Choices:
    waypoint = _waypoint(answer)
    if waypoint is None or waypoint.duration_s is None:
        return []
    update = {"waypoint": waypoint.model_copy(update={"duration_s": None})}
    return [[Change(update, f"waypoint.duration_s {waypoint.duration_s:.3f} -> None", "duration")]]


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
            Change({"brick_id": b.id}, f"brick_id {brick} -> {b.id} (placed)", "placed")
            for b in state.bricks
            if b.status == BrickStatus.PLACED and b.id != brick
        ],
        [
            Change({"target_index": t}, f"target_index {target} -> {t} (built)", "built")
            for t in sorted(built)
        ],
        [
            Change(
                {"target_index": t},
                f"target_index {target} -> {t} (its support is not built)",
                "unsupported",
            )
            for t in unsupported
        ],
    ]
    groups = [group for group in groups if group]
    if groups:
        return groups
    beyond = max(b.id for b in state.bricks) + 1 if state.bricks else 0
    return [[Change({"brick_id": beyond}, f"brick_id {brick} -> {beyond} (no such brick)", "none")]]


def _missing_field(answer: AgentAnswer, request: AgentRequest) -> Choices:
    changes: list[Change] = [
        Change({name: None}, f"{name} -> None", name)
        for name in DECISION_FIELDS
        if getattr(answer, name, None) is not None
    ]
    if isinstance(answer, GraspAnswer | SingleAgentAnswer) and answer.close:
        changes.append(Change({"close": False}, "close True -> False", "close"))
    return [[change] for change in changes]


def _near_offset(answer: AgentAnswer, request: AgentRequest, near: Near) -> Change | None:
    """The waypoint shifted horizontally by ``near.factor`` times its position tolerance,
    towards ``near.direction``."""
    waypoint, name = _waypoint(answer), _guard(answer, request)[0]
    if waypoint is None or name is None:
        return None
    tolerance = float(getattr(request.tolerances, name))
    shift = near.factor * tolerance
    x, y, z = waypoint.position_m
    moved = (x + shift * math.cos(near.direction), y + shift * math.sin(near.direction), z)
    update = {"waypoint": waypoint.model_copy(update={"position_m": moved})}
    toward = math.degrees(near.direction)
    return Change(
        update,
        f"waypoint.position_m {_short(waypoint.position_m)} -> {_short(moved)} (shifted "
        f"{shift:.4f} m toward {toward:.0f} deg from world x: {near.factor:.2f} x {name} "
        f"{tolerance:.4g})",
        near,
    )


def _near_yaw(answer: AgentAnswer, request: AgentRequest, near: Near) -> Change | None:
    """The waypoint turned about world z by ``near.direction`` x ``near.factor`` times its
    yaw tolerance."""
    waypoint, name = _waypoint(answer), _guard(answer, request)[1]
    if waypoint is None or name is None:
        return None
    tolerance = float(getattr(request.tolerances, name))
    turn = near.direction * near.factor * tolerance
    turned = _turned(waypoint, turn)
    detail = f"{turned.detail[:-1]}: {near.factor:.2f} x {name} {tolerance:.4g})"
    return Change(turned.update, detail, near)


#: What each kind but the near-misses can change in an answer.
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
#: Where a repeat may make a kind's mistake more widely than its first draw does.
REPEATS: dict[CorruptionKind, Callable[[AgentAnswer, AgentRequest], Choices]] = {
    CorruptionKind.CM_AS_M: _cm_as_m_again,
}
#: The near-misses: the change a drawn direction and factor make (None: it does not apply).
NEAR_CHANGES: dict[CorruptionKind, Callable[[AgentAnswer, AgentRequest, Near], Change | None]] = {
    CorruptionKind.NEAR_OFFSET: _near_offset,
    CorruptionKind.NEAR_YAW: _near_yaw,
}


# --- helpers ----------------------------------------------------------------------------


def _waypoint(answer: AgentAnswer) -> WaypointProposal | None:
    waypoint = getattr(answer, "waypoint", None)
    return waypoint if isinstance(waypoint, WaypointProposal) else None


def _step(answer: AgentAnswer, request: AgentRequest) -> str:
    """The step the answer is for: the agent's, or the single agent's ``step``."""
    step = answer.step if isinstance(answer, SingleAgentAnswer) else request.spec.key
    return str(step)


def _guard(answer: AgentAnswer, request: AgentRequest) -> tuple[str | None, str | None]:
    """The tolerances that guard the answer's waypoint, position and yaw
    (GUARDING_TOLERANCES); None where it has no waypoint or its step none."""
    if _waypoint(answer) is None:
        return None, None
    return GUARDING_TOLERANCES.get(_step(answer, request), (None, None))


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
    return Change(update, f"waypoint.position_m[{axis}] {old:.3f} -> {new:.3f}", axis)


def _moved_to(waypoint: WaypointProposal, position: Vec3, what: str, mark: Hashable) -> Change:
    update = {"waypoint": waypoint.model_copy(update={"position_m": tuple(position)})}
    old = _short(waypoint.position_m)
    return Change(update, f"waypoint.position_m {old} -> {_short(position)} ({what})", mark)


def _turned(waypoint: WaypointProposal, turn_deg: float) -> Change:
    """The waypoint's orientation turned by ``turn_deg`` about world z: R' = Rz(turn) R."""
    quat = yaw_turned(waypoint.quat_xyzw, math.radians(turn_deg))
    update = {"waypoint": waypoint.model_copy(update={"quat_xyzw": quat})}
    return Change(
        update,
        f"waypoint.quat_xyzw {_short(waypoint.quat_xyzw)} -> {_short(quat)} "
        f"(turned {turn_deg:+g} deg about world z)",
        turn_deg,
    )


def yaw_turned(quat_xyzw: QuatXYZW, angle_rad: float) -> QuatXYZW:
    """The quaternion of Rz(angle) * R, for R given by ``quat_xyzw`` (left as it is scaled:
    no normalisation)."""
    x, y, z, w = quat_xyzw
    c, s = math.cos(angle_rad / 2.0), math.sin(angle_rad / 2.0)
    return (c * x - s * y, c * y + s * x, c * z + s * w, c * w - s * z)


def _short(values: Sequence[float]) -> str:
    return "(" + ", ".join(f"{v:.3f}" for v in values) + ")"
