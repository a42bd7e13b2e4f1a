"""The gates sigma_1..sigma_6 of the paper, judged on measured tool outputs only.

A gate never reads what a reasoner claims: its inputs are tool reports computed from the
simulator (collision queries, pad forces, velocities, poses). Each returns a
:class:`GateVerdict` with the measured values and, when it fails, feedback that names
every failed check with its value and threshold, for the agent's next attempt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from actionreasoning.tools.collision import CollisionReport
from actionreasoning.tools.contact import ContactForces, SlipEstimate
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.world.tolerances import Tolerances


@dataclass(frozen=True)
class Check:
    """One inequality of a gate: a measured value against a threshold."""

    name: str
    value: float
    threshold: float
    at_most: bool  # True: value <= threshold passes; False: value >= threshold passes

    @property
    def passed(self) -> bool:
        """Whether the inequality holds; a value or threshold that is not finite (a NaN from
        a broken measurement, say) never passes."""
        if not (math.isfinite(self.value) and math.isfinite(self.threshold)):
            return False
        return self.value <= self.threshold if self.at_most else self.value >= self.threshold

    def describe(self) -> str:
        relation = "<=" if self.at_most else ">="
        return f"{self.name} = {self.value:.4g}, needs {relation} {self.threshold:.4g}"


@dataclass(frozen=True)
class GateVerdict:
    """The acceptance flag sigma_i with what was measured."""

    gate: str
    checks: tuple[Check, ...]

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    @property
    def measured(self) -> dict[str, float]:
        return {check.name: check.value for check in self.checks}

    @property
    def feedback(self) -> str:
        """Empty when passed; else every failed check, for the agent to correct."""
        failed = [check.describe() for check in self.checks if not check.passed]
        return f"{self.gate} failed: " + "; ".join(failed) if failed else ""


def _path_checks(
    report: CollisionReport, min_clearance_m: float, prefix: str = ""
) -> tuple[Check, ...]:
    """A path reachable and clear by ``min_clearance_m``; ``prefix`` names which path."""
    return (
        Check(f"{prefix}reachable", float(report.reachable), 1.0, at_most=False),
        Check(f"{prefix}clearance_m", report.clearance_m, min_clearance_m, at_most=False),
    )


def sigma1_pre_grasp(path: CollisionReport, tol: Tolerances) -> GateVerdict:
    """Path to the approach pose collision-free with clearance c >= c_min."""
    return GateVerdict("sigma1_pre_grasp", _path_checks(path, tol.c_min_m))


def sigma2_descent(
    opening_m: float,
    brick_width_m: float,
    pads: ContactForces,
    brick_shift_m: float,
    tol: Tolerances,
) -> GateVerdict:
    """Opening w >= w_brick + delta, no pad pressing on the brick, and the brick where it was
    before the descent (a pad that came down on its top and shoved it aside may touch
    nothing at the end). The shift compares two measurements, so under noise it is allowed
    eps_xy plus what the noise of two positions can show."""
    return GateVerdict(
        "sigma2_descent",
        (
            Check("opening_m", opening_m, brick_width_m + tol.delta_m, at_most=False),
            Check("sidewall_force_n", max(pads.normal_n), tol.sidewall_contact_n, at_most=True),
            Check("brick_shift_m", brick_shift_m, tol.eps_xy_m + tol.overlap_m, at_most=True),
        ),
    )


def _held(pads: ContactForces, tol: Tolerances) -> Check:
    """Both pads press with at least f_min = safety factor x m g / (2 mu)."""
    f_min = tol.grip_safety_factor * pads.required_normal_n
    return Check("normal_force_n", min(pads.normal_n), f_min, at_most=False)


def sigma3_grasp(
    pads: ContactForces, position_error_m: float, orientation_error_deg: float, tol: Tolerances
) -> GateVerdict:
    """Normal force f_n >= f_min on both pads (f_min from the brick's mass and mu), and grasp
    pose error <= eps_g."""
    return GateVerdict(
        "sigma3_grasp",
        (
            _held(pads, tol),
            Check("pose_error_m", position_error_m, tol.eps_g_m, at_most=True),
            Check("pose_error_deg", orientation_error_deg, tol.eps_g_deg, at_most=True),
        ),
    )


def sigma4_lift(slip: SlipEstimate, pads: ContactForces, tol: Tolerances) -> GateVerdict:
    """Held through the move: f_n >= f_min on both pads, brick speed relative to the gripper
    <= v_th, and the grasp's friction f_t <= mu f_n. How far the brick crept in the hand is
    not judged here: placement measures the brick in the hand again before setting it down.
    """
    return GateVerdict(
        "sigma4_lift",
        (
            _held(pads, tol),
            Check("relative_speed_mps", slip.relative_speed_mps, tol.v_th_mps, at_most=True),
            Check("friction_margin_n", pads.friction_margin_n, 0.0, at_most=False),
            Check("tilt_in_hand_deg", slip.tilt_in_hand_deg, tol.eps_tilt_deg, at_most=True),
        ),
    )


def sigma5_placement(alignment: AlignmentErrors, tol: Tolerances) -> GateVerdict:
    """d_perp <= eps_perp, |e_xy| <= eps_xy and |e_theta| <= eps_theta."""
    return GateVerdict(
        "sigma5_placement",
        (
            Check("d_perp_m", abs(alignment.d_perp_m), tol.eps_perp_m, at_most=True),
            Check("e_xy_m", alignment.e_xy_norm_m, tol.eps_xy_m, at_most=True),
            Check("e_theta_deg", abs(alignment.e_theta_deg), tol.eps_theta_deg, at_most=True),
        ),
    )


def lift_plan(
    sideways_m: float,
    turn_deg: float,
    path: CollisionReport,
    bottom_clearance_m: float,
    tol: Tolerances,
) -> GateVerdict:
    """Before a lift moves: straight up (no shift or turn beyond eps_g), collision-free from
    1 cm up, and ending with the held brick's bottom c_min above every other brick's top."""
    return GateVerdict(
        "lift_plan",
        (
            Check("sideways_m", sideways_m, tol.eps_g_m, at_most=True),
            Check("turn_deg", turn_deg, tol.eps_g_deg, at_most=True),
            *_path_checks(path, 0.0 - tol.overlap_m),
            Check("bottom_clearance_m", bottom_clearance_m, tol.c_min_m, at_most=False),
        ),
    )


def sigma6_return(
    retreat: CollisionReport, onward: CollisionReport, tol: Tolerances
) -> GateVerdict:
    """The whole return collision-free, the straight retreat from the slot and the joint move
    on to the ready pose: no overlap beyond what sensing noise can show."""
    return GateVerdict(
        "sigma6_return",
        (
            *_path_checks(retreat, -tol.overlap_m, prefix="retreat_"),
            *_path_checks(onward, -tol.overlap_m, prefix="return_"),
        ),
    )
