"""Reachability: can the tool centre point reach a pose, and how well (IK on the arm model)."""

from __future__ import annotations

from pydantic import Field

from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.world.models import Pose


class ReachQuery(ToolModel):
    """A tool-centre-point pose to test (world frame, quaternion x, y, z, w)."""

    pose: Pose


class ReachReport(ToolModel):
    """The IK answer for a pose."""

    reachable: bool = Field(description="Reached within 0.1 mm and 0.05 deg.")
    joints_rad: tuple[float, ...] = Field(description="Arm joint angles of the best solution.")
    position_error_m: float
    orientation_error_deg: float
    joint_limit_margin_rad: float = Field(description="Smallest distance of a joint to a limit.")


def reachability(context: ToolContext, query: ReachQuery) -> ReachReport:
    """Whether the arm reaches a pose: IK solution, remaining errors and joint-limit margin."""
    solution = context.arm.solve(query.pose.position_m, query.pose.quat_xyzw)
    return ReachReport(
        reachable=solution.reached,
        joints_rad=solution.joints_rad,
        position_error_m=solution.position_error_m,
        orientation_error_deg=solution.orientation_error_deg,
        joint_limit_margin_rad=solution.joint_limit_margin_rad,
    )


REACHABILITY = tool("reachability", reachability)
