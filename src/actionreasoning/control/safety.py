"""Safety limits of the controller, whoever commands it: checked on the planned tool path
before the arm moves, so a violating waypoint is refused, never half executed.

* the tool centre point stays inside the scene's workspace box and above a minimum height;
* in transit (a free move, away from where it starts and ends) it passes above every
  brick it crosses, except the one in the hand, with a clearance;
* its peak speed stays below a maximum;
* joint limits hold by construction: IK clips to them and a pose it cannot reach inside
  them raises :class:`~actionreasoning.errors.UnreachableError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydantic import NonNegativeFloat, PositiveFloat

from actionreasoning.errors import TrialAborted
from actionreasoning.records import FailureCode
from actionreasoning.world.boxes import Box
from actionreasoning.world.geometry import Vec3
from actionreasoning.world.scene_spec import WorkspaceBox

#: How far the hand reaches sideways past a brick it passes over.
HAND_RADIUS_M = 0.05


@dataclass(frozen=True)
class SafetyLimits:
    """The envelope every commanded motion must stay in, inside the scene's workspace box."""

    min_height_m: NonNegativeFloat = 0.02  # above the ground (z = 0)
    #: Tool centre point above a crossed brick's top. A held brick hangs 3 cm below it, so its
    #: bottom clears the brick by 1 cm; the built-in policies pass with 4.7 cm or more.
    transit_clearance_m: NonNegativeFloat = 0.04
    #: Path points this close (horizontally) to the start or the end are not in transit:
    #: there the agents' own checks and gates govern the approach.
    transit_margin_m: NonNegativeFloat = 0.10
    #: The classical script's two-second transfer peaks at about 2.1 m/s.
    max_tcp_speed_mps: PositiveFloat = 2.5  # a move's least time divides by it


def check_motion(
    path: Sequence[Vec3],
    duration_s: float,
    peak_factor: float,
    obstacles: Sequence[Box],
    workspace: WorkspaceBox,
    limits: SafetyLimits,
) -> None:
    """Raise ``TrialAborted("safety_limit", ...)`` if the tool path breaks a limit.

    ``obstacles`` are the bricks to clear in transit: those of a free move, none for a
    straight (linear) one. The tool is over a brick within its half diagonal plus
    ``HAND_RADIUS_M`` of its centre. ``workspace`` is the scene's box."""
    points = np.asarray(path, dtype=float)
    if not np.all(np.isfinite(points)):
        _refuse("the planned tool path is not finite")
    for point in points:
        if not workspace.contains(tuple(point)):
            _refuse(f"the tool would leave the workspace box at {_fmt(point)}")
        if point[2] < limits.min_height_m:
            _refuse(
                f"the tool would go down to {point[2]:.3f} m at {_fmt(point)}, below the "
                f"{limits.min_height_m} m minimum height"
            )
    length = float(np.sum(np.linalg.norm(np.diff(points, axis=0), axis=1)))
    speed = peak_factor * length / max(duration_s, 1e-9)
    if speed > limits.max_tcp_speed_mps:
        _refuse(
            f"the tool would reach {speed:.2f} m/s over {length:.3f} m in {duration_s:.3f} s, "
            f"above the {limits.max_tcp_speed_mps} m/s limit"
        )
    _check_transit(points, obstacles, limits)


def _check_transit(points: np.ndarray, obstacles: Sequence[Box], limits: SafetyLimits) -> None:
    start, end = points[0, :2], points[-1, :2]
    margin = limits.transit_margin_m
    radii = [math.hypot(o.size_m[0], o.size_m[1]) / 2.0 + HAND_RADIUS_M for o in obstacles]
    for point in points:
        xy = point[:2]
        if min(np.linalg.norm(xy - start), np.linalg.norm(xy - end)) <= margin:
            continue
        for obstacle, radius in zip(obstacles, radii, strict=True):
            over = np.linalg.norm(xy - np.asarray(obstacle.position_m[:2])) <= radius
            if over and point[2] < obstacle.top_m + limits.transit_clearance_m:
                _refuse(
                    f"in transit the tool would pass {point[2] - obstacle.top_m:.3f} m above "
                    f"brick {obstacle.id} at {_fmt(point)}, less than the "
                    f"{limits.transit_clearance_m} m clearance"
                )


def _fmt(point: np.ndarray) -> str:
    return "(" + ", ".join(f"{v:.3f}" if math.isfinite(v) else str(v) for v in point) + ") m"


def _refuse(detail: str) -> None:
    raise TrialAborted(FailureCode.SAFETY_LIMIT, detail)
