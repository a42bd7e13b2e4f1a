"""Output schemas Omega_i: what each agent must answer, as pydantic models.

Every answer is data (JSON), validated before anything runs: a waypoint is a position and
a unit quaternion (x, y, z, w) in the world frame, a gripper command and how to move;
tool calls name whitelisted tools with their arguments. Never code.

Each agent has two kinds of model. Its answer model (``PreGraspAnswer``, ...) is the schema
a model is shown and sent: every decision field may be left out, since an answer that
lists ``tool_calls`` is a tool turn. Its decision (``PreGraspDecision``, ...) is the same
answer complete: a subclass whose decision fields are required, validated from the answer
(:meth:`AgentAnswer.of`) and refused, naming what is missing, if it leaves one out.
:data:`DECISIONS` says which decision each answer model must make once it calls no tools.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Annotated, Any, ClassVar, Final, Literal, Self

from pydantic import BaseModel, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from actionreasoning.world.geometry import QUAT_NORM_TOLERANCE, QuatXYZW, Vec3
from actionreasoning.world.motion import MAX_MOVE_S
from actionreasoning.world.scene_spec import GRIPPER_GAP_M
from actionreasoning.world.stages import Stage


class _Output(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class ToolCall(_Output):
    """A request to run one tool of the agent's knowledge base."""

    name: str = Field(max_length=64)
    arguments: dict[str, Any] = Field(default_factory=dict)


class WaypointProposal(_Output):
    """A tool-centre-point target and how to get there."""

    position_m: Vec3
    quat_xyzw: QuatXYZW
    path: Literal["joint", "linear"] = "joint"
    duration_s: float | None = Field(
        None,
        gt=0.0,
        le=MAX_MOVE_S,
        description="Least time the move takes; a slower move loads the grip less. null: as "
        "fast as the controller's speed limits allow.",
    )


def unit_waypoint(waypoint: WaypointProposal, path: str | None = None) -> WaypointProposal:
    """The waypoint with its quaternion normalised (and ``path`` if given).

    Raises ValueError when the norm is further than QUAT_NORM_TOLERANCE from 1.
    """
    norm = math.sqrt(sum(q * q for q in waypoint.quat_xyzw))
    if abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
        raise ValueError(f"quaternion norm {norm:.4f} is not 1")
    return waypoint.model_copy(
        update={
            "quat_xyzw": tuple(q / norm for q in waypoint.quat_xyzw),
            "path": path or waypoint.path,
        }
    )


#: A brick's id or a target's index, as an answer names it.
Index = Annotated[int, Field(ge=0)]
#: A gripper opening (m) within the gripper's range.
Opening = Annotated[float, Field(ge=GRIPPER_GAP_M[0], le=GRIPPER_GAP_M[1])]


class AgentAnswer(_Output):
    """Fields every agent answers with."""

    tool_calls: list[ToolCall] = Field(
        default_factory=list, max_length=8, description="Tools to run first."
    )
    rationale: str = Field("", max_length=600, description="One or two sentences: why.")

    @classmethod
    def of(cls, answer: AgentAnswer) -> Self:
        """``answer``'s fields validated as this model (raises pydantic's ValidationError)."""
        return cls.model_validate(dict(answer))


class Decision(AgentAnswer):
    """A complete decision: an answer model's subclass whose decision fields are required.

    Validation refuses an answer that leaves one out (or null) with one error of type
    ``answer_complete`` whose message is ``incomplete``, filled in with the fields it
    ``needs`` and those ``missing``.
    """

    incomplete: ClassVar[str] = "the answer needs {needs}; missing: {missing}"

    @model_validator(mode="before")
    @classmethod
    def _complete(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        needs = [name for name, field in cls.model_fields.items() if field.is_required()]
        missing = [name for name in needs if data.get(name) is None]
        if missing:
            context = {"needs": ", ".join(needs), "missing": ", ".join(missing)}
            raise PydanticCustomError("answer_complete", cls.incomplete, context)
        return data


class PreGraspAnswer(AgentAnswer):
    """Agent 1: which brick goes to which target next, and the approach pose above it."""

    brick_id: Index | None = None
    target_index: Index | None = None
    waypoint: WaypointProposal | None = None


class PreGraspDecision(PreGraspAnswer, Decision):
    """Agent 1's decision: the brick, its target and the approach pose."""

    brick_id: Index
    target_index: Index
    waypoint: WaypointProposal


class PreGraspSeenAnswer(AgentAnswer):
    """Agent 1 in the image tier: which target next, and the approach pose above the brick
    for it, which names the brick: the one under the approach pose."""

    target_index: Index | None = None
    waypoint: WaypointProposal | None = None


class PreGraspSeenDecision(PreGraspSeenAnswer, Decision):
    """Agent 1's decision in the image tier: the target and the approach pose."""

    target_index: Index
    waypoint: WaypointProposal


class DescentAnswer(AgentAnswer):
    """Agent 2: the gripper opening and the grasp pose to descend to."""

    gripper_opening_m: Opening | None = None
    waypoint: WaypointProposal | None = None


class DescentDecision(DescentAnswer, Decision):
    """Agent 2's decision: the opening and the grasp pose."""

    gripper_opening_m: Opening
    waypoint: WaypointProposal


class GraspAnswer(AgentAnswer):
    """Agent 3: close the gripper where the tool is, or at a corrected pose."""

    close: bool = False
    waypoint: WaypointProposal | None = Field(
        None,
        description="Where to close, reached straight from where the tool is (after a "
        "refused grasp: the tool pose shifted and turned by the refusal's errors); null: "
        "where the tool is.",
    )


class LiftAnswer(AgentAnswer):
    """Agent 4: the safe-lift pose straight above the grasp."""

    waypoint: WaypointProposal | None = None


class LiftDecision(LiftAnswer, Decision):
    """Agent 4's decision: the safe-lift pose."""

    waypoint: WaypointProposal


class PlacementAnswer(AgentAnswer):
    """Agent 5: the slot pose to set the brick down at, or a re-grasp."""

    waypoint: WaypointProposal | None = None
    regrasp: bool = Field(
        False,
        description="Set the brick down near by and grasp it again.",
    )


class PlacementDecision(PlacementAnswer, Decision):
    """Agent 5's decision to place: the slot pose (``regrasp`` false)."""

    waypoint: WaypointProposal


class RegraspRequest(PlacementAnswer, Decision):
    """Agent 5's decision to grasp the brick again (``regrasp`` true); a waypoint given with
    it is not used."""


def placement_decision(answer: AgentAnswer) -> PlacementDecision | RegraspRequest:
    """Agent 5's answer as its decision: a re-grasp if it asks for one, else a placement."""
    if isinstance(answer, PlacementAnswer) and answer.regrasp:
        return RegraspRequest.of(answer)
    return PlacementDecision.of(answer)


class ReleaseAnswer(AgentAnswer):
    """Agent 6: the opening to release with and the ready pose to return to."""

    gripper_opening_m: Opening | None = None
    waypoint: WaypointProposal | None = None


class ReleaseDecision(ReleaseAnswer, Decision):
    """Agent 6's decision: the opening and the ready pose."""

    gripper_opening_m: Opening
    waypoint: WaypointProposal


#: The single agent's steps: the six agents' stages, in the order of a brick's cycle.
SingleAgentStep = Literal[
    Stage.PRE_GRASP,
    Stage.DESCENT,
    Stage.GRASP,
    Stage.LIFT,
    Stage.PLACEMENT,
    Stage.RELEASE,
]


class SingleAgentAnswer(AgentAnswer):
    """The single-agent ablation: one agent answers every stage of a brick's cycle, with the
    fields the six agents answer. ``step`` names the stage answered (memory.step); the
    stage's own fields are read, as its agent's answer would be (:func:`stage_answer`), the
    others not."""

    step: SingleAgentStep | None = Field(
        None, description="The stage answered: memory.step (a tool turn may leave it out)."
    )
    brick_id: Index | None = Field(None, description="pre_grasp: the brick to pick.")
    target_index: Index | None = Field(None, description="pre_grasp: its target.")
    waypoint: WaypointProposal | None = Field(
        None,
        description="The stage's tool pose: the approach, the grasp pose, the lift's end, "
        "the slot, the pose to return to; grasp: only to close elsewhere than where the "
        "tool is.",
    )
    gripper_opening_m: Opening | None = Field(
        None, description="descent: the opening to descend with; release: to let go with."
    )
    close: bool = Field(False, description="grasp: true, to close the gripper.")
    regrasp: bool = Field(
        False, description="placement: set the brick down near by and grasp it again."
    )


#: The answer model of each stage, which the single agent's answer is read as.
STAGE_ANSWERS: Final[Mapping[Stage, type[AgentAnswer]]] = {
    Stage.PRE_GRASP: PreGraspAnswer,
    Stage.DESCENT: DescentAnswer,
    Stage.GRASP: GraspAnswer,
    Stage.LIFT: LiftAnswer,
    Stage.PLACEMENT: PlacementAnswer,
    Stage.RELEASE: ReleaseAnswer,
}


def stage_answer(stage: Stage, answer: SingleAgentAnswer) -> AgentAnswer:
    """The single agent's answer read as the answer of ``stage``'s agent: the fields that
    agent answers, unvalidated (its decision is validated as any agent's)."""
    model = STAGE_ANSWERS[stage]
    return model.model_construct(**{name: getattr(answer, name) for name in model.model_fields})


class SingleAgentDecision(SingleAgentAnswer, Decision):
    """The single agent's decision: it names its step."""

    step: SingleAgentStep


def single_agent_decision(answer: AgentAnswer) -> AgentAnswer:
    """The single agent's answer as its step's decision (what the step's agent decides)."""
    decided = SingleAgentDecision.of(answer)
    return DECISIONS[STAGE_ANSWERS[decided.step]](stage_answer(decided.step, decided))


#: Each answer model's decision, as a function of an answer that calls no more tools (it
#: raises pydantic's ValidationError on an incomplete one). Agent 3 decides nothing it
#: could leave out: close or not, where the tool is or at a waypoint. The single agent
#: decides what its step's agent decides.
DECISIONS: Final[Mapping[type[AgentAnswer], Callable[[AgentAnswer], AgentAnswer]]] = {
    PreGraspAnswer: PreGraspDecision.of,
    PreGraspSeenAnswer: PreGraspSeenDecision.of,
    DescentAnswer: DescentDecision.of,
    GraspAnswer: GraspAnswer.of,
    LiftAnswer: LiftDecision.of,
    PlacementAnswer: placement_decision,
    ReleaseAnswer: ReleaseDecision.of,
    SingleAgentAnswer: single_agent_decision,
}
