"""Output schemas Omega_i: what each agent must answer, as pydantic models.

Every answer is data (JSON), validated before anything runs: a waypoint is a position and
a unit quaternion (x, y, z, w) in the world frame, a gripper command and how to move;
tool calls name whitelisted tools with their arguments. Never code.
"""

from __future__ import annotations

import math
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

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


class AgentAnswer(_Output):
    """Fields every agent answers with."""

    tool_calls: list[ToolCall] = Field(
        default_factory=list, max_length=8, description="Tools to run first."
    )
    rationale: str = Field("", max_length=600, description="One or two sentences: why.")


class PreGraspAnswer(AgentAnswer):
    """Agent 1: which brick goes to which target next, and the approach pose above it."""

    brick_id: int | None = Field(None, ge=0)
    target_index: int | None = Field(None, ge=0)
    waypoint: WaypointProposal | None = None


class DescentAnswer(AgentAnswer):
    """Agent 2: the gripper opening and the grasp pose to descend to."""

    gripper_opening_m: float | None = Field(None, ge=GRIPPER_GAP_M[0], le=GRIPPER_GAP_M[1])
    waypoint: WaypointProposal | None = None


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


class PlacementAnswer(AgentAnswer):
    """Agent 5: the slot pose to set the brick down at, or a re-grasp."""

    waypoint: WaypointProposal | None = None
    regrasp: bool = Field(
        False,
        description="Set the brick down near by and grasp it again.",
    )


class ReleaseAnswer(AgentAnswer):
    """Agent 6: the opening to release with and the ready pose to return to."""

    gripper_opening_m: float | None = Field(None, ge=GRIPPER_GAP_M[0], le=GRIPPER_GAP_M[1])
    waypoint: WaypointProposal | None = None


#: The single agent's steps: every stage in order, then ``done``.
SingleAgentStep = Literal[
    Stage.PRE_GRASP,
    Stage.DESCENT,
    Stage.GRASP,
    Stage.LIFT,
    Stage.TRANSFER,
    Stage.PLACEMENT,
    Stage.RELEASE,
    Stage.RETREAT,
    "done",
]


class SingleAgentAnswer(AgentAnswer):
    """The single-agent ablation: the next waypoint of the whole cycle and a gripper command.

    The gripper command is applied once the arm has reached the waypoint (or where it is,
    without a waypoint). ``pre_grasp`` names the brick and the target; ``done`` ends the
    build after moving to its waypoint, if any.
    """

    step: SingleAgentStep
    brick_id: int | None = Field(None, ge=0)
    target_index: int | None = Field(None, ge=0)
    waypoint: WaypointProposal | None = None
    gripper: Literal["open", "close", "hold"] = "hold"
    gripper_opening_m: float | None = Field(None, ge=GRIPPER_GAP_M[0], le=GRIPPER_GAP_M[1])
