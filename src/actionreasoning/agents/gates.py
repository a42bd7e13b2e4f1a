"""The gates sigma_1..sigma_6 of the paper, judged on measured tool outputs only.

A gate never reads what a reasoner claims: its inputs are tool reports computed from the
simulator (collision queries, pad forces, velocities, poses). Each returns a
:class:`GateVerdict` with the measured values and, when it fails, feedback that names
every failed check with its value and threshold, for the agent's next attempt.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from actionreasoning.agents.feedback import FailedCheck, Measured, Refusal
from actionreasoning.tools.collision import CollisionReport
from actionreasoning.tools.contact import ContactForces, SlipEstimate
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.tools.placement import PlacementPose
from actionreasoning.world.motion import MAX_MOVE_S
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import NOISE_SIGMAS, Tolerances


@dataclass(frozen=True)
class Check:
    """One inequality of a gate: a measured value against a threshold."""

    name: str
    value: float
    threshold: float
    at_most: bool  # True: value <= threshold passes; False: value >= threshold passes

    def __post_init__(self) -> None:
        # A threshold of -0.0 (minus a zero tolerance) is 0: shown and recorded as such.
        object.__setattr__(self, "threshold", self.threshold + 0.0)

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
    """The acceptance flag sigma_i with what was measured: each check, and the signed errors
    (world frame) the next answer can correct by."""

    gate: str
    checks: tuple[Check, ...]
    measured: Measured = Measured()
    note: str = ""

    @property
    def passed(self) -> bool:
        return all(check.passed for check in self.checks)

    def refusal(self, agent: str) -> Refusal:
        """The refusal of ``agent``'s answer: the failed checks and the measurements."""
        failed = tuple(
            FailedCheck(
                name=c.name,
                value=c.value,
                relation="<=" if c.at_most else ">=",
                threshold=c.threshold,
            )
            for c in self.checks
            if not c.passed
        )
        return Refusal(
            agent=agent, gate=self.gate, failed=failed, measured=self.measured, note=self.note
        )

    @property
    def feedback(self) -> str:
        """Empty when passed; else every failed check and what was measured."""
        return "" if self.passed else self.refusal("").text()

    def noted(self, note: str) -> GateVerdict:
        """This verdict with ``note`` saying what happened."""
        return replace(self, note=note)


def _path_checks(
    report: CollisionReport, min_clearance_m: float, prefix: str = ""
) -> tuple[Check, ...]:
    """A path reachable and clear by ``min_clearance_m``; ``prefix`` names which path."""
    return (
        Check(f"{prefix}reachable", float(report.reachable), 1.0, at_most=False),
        Check(f"{prefix}clearance_m", report.clearance_m, min_clearance_m, at_most=False),
    )


def _path_measured(*reports: CollisionReport) -> Measured:
    """The least clearance of ``reports`` and what came closest there."""
    worst = min(reports, key=lambda r: r.clearance_m if r.reachable else -math.inf)
    return Measured(clearance_m=worst.clearance_m, closest=worst.closest)


def sigma1_pre_grasp(path: CollisionReport, tol: Tolerances) -> GateVerdict:
    """Path to the approach pose collision-free with clearance c >= c_min."""
    return GateVerdict(
        "sigma1_pre_grasp", _path_checks(path, tol.c_min_m), measured=_path_measured(path)
    )


def sigma2_descent(
    opening_m: float,
    brick_width_m: float,
    pads: ContactForces,
    brick_shift_m: tuple[float, float],
    tol: Tolerances,
) -> GateVerdict:
    """Opening w >= w_brick + delta, no pad pressing on the brick, and the brick where it was
    before the descent (a pad that came down on its top and shoved it aside may touch
    nothing at the end). The shift compares two measurements, so under noise it is allowed
    eps_xy plus what the noise of two positions can show. The correction is the brick's
    shift: where the grasp must move to."""
    dx, dy = brick_shift_m
    return GateVerdict(
        "sigma2_descent",
        (
            Check("opening_m", opening_m, brick_width_m + tol.delta_m, at_most=False),
            Check("sidewall_force_n", max(pads.normal_n), tol.sidewall_contact_n, at_most=True),
            Check("brick_shift_m", math.hypot(dx, dy), tol.eps_xy_m + tol.overlap_m, at_most=True),
        ),
        measured=Measured(e_x_m=dx, e_y_m=dy, pad_forces_n=pads.normal_n),
    )


def _held(pads: ContactForces, tol: Tolerances) -> Check:
    """Both pads press with at least f_min (``Tolerances.f_min_n``)."""
    required = tol.f_min_n(pads.required_normal_n)
    return Check("normal_force_n", min(pads.normal_n), required, at_most=False)


def _friction_margin(pads: ContactForces, tol: Tolerances) -> Check:
    """The grasp's friction left with the least friction the brick may have, friction_factor
    x mu x (sum of normal forces) - (sum of friction forces), at least minus what the
    force noise can show (NOISE_SIGMAS standard deviations of that difference)."""
    grip = tol.friction_factor * pads.friction_coefficient * sum(pads.normal_n)
    load = sum(pads.tangential_n)
    noise = NOISE_SIGMAS * tol.force_noise * math.hypot(grip, load)
    return Check("friction_margin_n", grip - load, -noise, at_most=False)


def sigma3_grasp(
    pads: ContactForces,
    offset_m: tuple[float, float, float],
    yaw_error_deg: float,
    tol: Tolerances,
) -> GateVerdict:
    """Normal force f_n >= f_min on both pads, and grasp pose error <= eps_g: ``offset_m`` is
    the brick's centre minus the tool's (world x, y, z), ``yaw_error_deg`` the brick's yaw
    minus the tool's, modulo a half turn (the pads grip a brick turned 180 deg the same)."""
    return GateVerdict(
        "sigma3_grasp",
        (
            _held(pads, tol),
            Check("pose_error_m", math.hypot(*offset_m), tol.eps_g_m, at_most=True),
            Check("pose_error_deg", abs(yaw_error_deg), tol.eps_g_deg, at_most=True),
        ),
        measured=Measured(
            e_x_m=offset_m[0],
            e_y_m=offset_m[1],
            e_z_m=offset_m[2],
            e_theta_deg=yaw_error_deg,
            pad_forces_n=pads.normal_n,
        ),
    )


def creep_hold_m(tol: Tolerances) -> float:
    """How far a brick may creep in the hand before it leaves the pads' hold: v_th over the
    longest move."""
    return tol.v_th_mps * MAX_MOVE_S


def creep_limit_mps(carry_s: float, tol: Tolerances) -> float:
    """The fastest a brick may creep in the hand and still be carried: v_th, at which it
    stays in the hand over the longest move; or, faster, the speed at which it would creep
    out of the pads' hold (:func:`creep_hold_m`) only in ``carry_s``, the time its carry
    over the slot and set-down take at the carry speed (a light brick creeps steadily at
    rest: ``bench/hand_creep.py``)."""
    return max(tol.v_th_mps, creep_hold_m(tol) / max(carry_s, 1e-9))


def sigma4_lift(
    slip: SlipEstimate,
    pads: ContactForces,
    set_down: PlacementPose,
    move_speed_mps: float,
    tol: Tolerances,
    carry_s: float = MAX_MOVE_S,
) -> GateVerdict:
    """Held through the move: f_n >= f_min on both pads, brick speed relative to the gripper
    <= v_th (or, if it creeps faster, slow enough to last the ``carry_s`` of its carry and
    set-down: :func:`creep_limit_mps`), and the grasp's friction f_t <= mu f_n (with the
    least mu the brick may have);
    and a brick that rolled in the hand can still be set down level: ``set_down``, its slot
    pose as it sits in the hand now with the tool tilted by the roll, is reachable with a
    clear way over the slot and down. How far it
    crept in the hand is not judged here: placement measures it again."""
    return GateVerdict(
        "sigma4_lift",
        (
            _held(pads, tol),
            Check(
                "relative_speed_mps",
                slip.relative_speed_mps,
                # v_th, as before, unless it creeps faster: then what its carry allows.
                tol.v_th_mps
                if slip.relative_speed_mps <= tol.v_th_mps
                else creep_limit_mps(carry_s, tol),
                at_most=True,
            ),
            _friction_margin(pads, tol),
            Check("set_down_reachable", float(set_down.reachable), 1.0, at_most=False),
            Check("set_down_clearance_m", set_down.way_clearance_m, -tol.overlap_m, False),
        ),
        measured=Measured(
            tilt_deg=slip.tilt_in_hand_deg,
            pad_forces_n=pads.normal_n,
            slip_speed_mps=slip.relative_speed_mps,
            move_speed_mps=move_speed_mps,
            clearance_m=set_down.way_clearance_m,
            closest=set_down.closest,
        ),
    )


def sigma5_placement(alignment: AlignmentErrors, tol: Tolerances) -> GateVerdict:
    """d_perp <= eps_perp, |e_xy| <= eps_xy, |e_theta| <= eps_theta and the brick's tilt
    <= eps_tilt; and, never widened, the success rule itself on the measured pose (centre
    offset and rotation). The correction is the target minus the brick: shift and turn the
    next slot by it."""
    return GateVerdict(
        "sigma5_placement",
        (
            *_seat_checks(alignment, tol),
            Check("offset_m", alignment.offset_m, tol.max_offset_m, at_most=True),
            Check("rotation_deg", alignment.rotation_deg, tol.max_rotation_deg, at_most=True),
        ),
        measured=misalignment(alignment),
    )


def sigma1_placed(alignment: AlignmentErrors, tol: Tolerances) -> GateVerdict:
    """A brick already placed, re-measured before the next is picked: still within
    max_offset_m and max_rotation_deg of its target (the success rule's limits)."""
    return GateVerdict(
        "sigma1_placed",
        (
            Check("offset_m", alignment.offset_m, tol.max_offset_m, at_most=True),
            Check("rotation_deg", alignment.rotation_deg, tol.max_rotation_deg, at_most=True),
        ),
        measured=misalignment(alignment),
    )


def sigma6_at_rest(
    alignment: AlignmentErrors,
    speed_mps: float,
    angular_speed_radps: float,
    tol: Tolerances,
    rule: SuccessRule = SuccessRule(),
) -> GateVerdict:
    """The released brick once the arm has left it, as the success rule will judge it after
    the whole build: at rest (the rule's speeds) and within max_offset_m and
    max_rotation_deg of its target."""
    return GateVerdict(
        "sigma6_at_rest",
        (
            Check("speed_mps", speed_mps, rule.max_speed_mps, at_most=True),
            Check("angular_speed_radps", angular_speed_radps, rule.max_angular_speed_radps, True),
            Check("offset_m", alignment.offset_m, tol.max_offset_m, at_most=True),
            Check("rotation_deg", alignment.rotation_deg, tol.max_rotation_deg, at_most=True),
        ),
        measured=misalignment(alignment),
    )


def misalignment(alignment: AlignmentErrors) -> Measured:
    """Alignment errors as feedback: the target minus the brick, to shift and turn by."""
    return Measured(
        e_x_m=alignment.e_xy_m[0],
        e_y_m=alignment.e_xy_m[1],
        e_theta_deg=alignment.e_theta_deg,
        d_perp_m=alignment.d_perp_m,
        tilt_deg=alignment.tilt_deg,
    )


def _seat_checks(alignment: AlignmentErrors, tol: Tolerances) -> tuple[Check, ...]:
    return (
        Check("d_perp_m", abs(alignment.d_perp_m), tol.eps_perp_m, at_most=True),
        Check("e_xy_m", alignment.e_xy_norm_m, tol.eps_xy_m, at_most=True),
        Check("e_theta_deg", abs(alignment.e_theta_deg), tol.eps_theta_deg, at_most=True),
        Check("tilt_deg", alignment.tilt_deg, tol.eps_tilt_deg, at_most=True),
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
        measured=_path_measured(retreat, onward),
    )
