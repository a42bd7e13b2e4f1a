"""Every gate passes and fails on measurements built for the purpose."""

from __future__ import annotations

import pytest

from actionreasoning.agents.gates import (
    lift_plan,
    sigma1_pre_grasp,
    sigma2_descent,
    sigma3_grasp,
    sigma4_lift,
    sigma5_placement,
    sigma6_return,
)
from actionreasoning.tools.collision import CollisionReport
from actionreasoning.tools.contact import ContactForces, SlipEstimate
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.world.models import Sensing
from actionreasoning.world.tolerances import Tolerances

TOL = Tolerances()
NOISY = TOL.under(Sensing(position_std_m=0.002))  # two positions' noise: 8.5 mm of overlap
W = 0.095


def path(clearance_m: float, reachable: bool = True) -> CollisionReport:
    return CollisionReport(
        reachable=reachable,
        collision_free=reachable and clearance_m > 0,
        clearance_m=clearance_m,
        closest="gripper_finger_left vs brick 2",
        poses_checked=10,
    )


def pads(left: float, right: float, tangential: float = 0.0, mass_kg: float = 1.5) -> ContactForces:
    """Pad forces on a brick of ``mass_kg`` held with mu = 0.6 (pads 1.2 x brick 0.5)."""
    mu = 0.6
    return ContactForces(
        brick_id=0,
        held=left > 1 and right > 1,
        normal_n=(left, right),
        tangential_n=(tangential, tangential),
        friction_coefficient=mu,
        friction_margin_n=mu * (left + right) - 2 * tangential,
        required_normal_n=mass_kg * 9.81 / (2 * mu),
    )


def slip(speed: float, tilt_deg: float = 0.0) -> SlipEstimate:
    return SlipEstimate(
        brick_id=0,
        relative_speed_mps=speed,
        relative_angular_speed_radps=0.0,
        offset_in_gripper_m=(0.0, 0.0, 0.0),
        tilt_in_hand_deg=tilt_deg,
    )


def aligned(e_xy: float = 0.0, e_theta: float = 0.0, d_perp: float = 0.0) -> AlignmentErrors:
    return AlignmentErrors(
        e_xy_m=(e_xy, 0.0), e_xy_norm_m=e_xy, e_theta_deg=e_theta, d_perp_m=d_perp, tilt_deg=0.0
    )


CASES = {
    "sigma1 clear": (sigma1_pre_grasp(path(0.05), TOL), True, ""),
    "sigma1 too close": (sigma1_pre_grasp(path(0.01), TOL), False, "clearance_m = 0.01"),
    "sigma1 unreachable": (sigma1_pre_grasp(path(0.3, reachable=False), TOL), False, "reachable"),
    "sigma2 open": (sigma2_descent(0.16, W, pads(0, 0), 0.0, TOL), True, ""),
    "sigma2 narrow": (sigma2_descent(0.11, W, pads(0, 0), 0.0, TOL), False, "opening_m = 0.11"),
    "sigma2 shoved": (
        sigma2_descent(0.16, W, pads(0, 0), 0.03, TOL),
        False,
        "brick_shift_m = 0.03",
    ),
    "sigma2 shift within noise": (sigma2_descent(0.16, W, pads(0, 0), 0.005, NOISY), True, ""),
    "sigma2 sidewall": (sigma2_descent(0.16, W, pads(3.0, 0), 0.0, TOL), False, "sidewall_force_n"),
    "sigma3 firm": (sigma3_grasp(pads(40, 38), 0.001, 0.2, TOL), True, ""),
    "sigma3 weak pad": (sigma3_grasp(pads(40, 20), 0.001, 0.2, TOL), False, "normal_force_n"),
    # f_min follows the brick: 2 x 3 kg x 9.81 / (2 x 0.6) = 49 N is more than 40 N.
    "sigma3 heavy brick": (
        sigma3_grasp(pads(40, 40, mass_kg=3.0), 0.001, 0.2, TOL),
        False,
        "needs >= 49.05",
    ),
    "sigma3 off pose": (sigma3_grasp(pads(110, 110), 0.01, 0.2, TOL), False, "pose_error_m"),
    "sigma4 held": (sigma4_lift(slip(0.001), pads(40, 40, 10), TOL), True, ""),
    "sigma4 slipping": (sigma4_lift(slip(0.02), pads(40, 40, 10), TOL), False, "relative_speed"),
    "sigma4 friction": (sigma4_lift(slip(0.0), pads(40, 40, 30), TOL), False, "friction_margin"),
    "sigma4 dropped": (sigma4_lift(slip(0.0), pads(0, 0, 0), TOL), False, "normal_force"),
    "sigma4 rolled": (
        sigma4_lift(slip(0.0, tilt_deg=TOL.eps_tilt_deg + 5), pads(40, 40, 10), TOL),
        False,
        "tilt_in_hand_deg",
    ),
    "sigma5 aligned": (sigma5_placement(aligned(0.001, 0.2, 0.001), TOL), True, ""),
    "sigma5 offset": (sigma5_placement(aligned(e_xy=0.004), TOL), False, "e_xy_m = 0.004"),
    "sigma5 turned": (sigma5_placement(aligned(e_theta=-1.0), TOL), False, "e_theta_deg = 1"),
    "sigma5 hovering": (sigma5_placement(aligned(d_perp=0.01), TOL), False, "d_perp_m = 0.01"),
    "sigma6 clear": (sigma6_return(path(0.002), path(0.1), TOL), True, ""),
    "sigma6 collides": (
        sigma6_return(path(-0.004), path(0.1), TOL),
        False,
        "retreat_clearance_m = -0.004",
    ),
    "sigma6 within noise": (sigma6_return(path(-0.004), path(0.1), NOISY), True, ""),
    "sigma6 return collides": (
        sigma6_return(path(0.01), path(-0.02), TOL),
        False,
        "return_clearance_m = -0.02",
    ),
    "sigma6 ready out of reach": (
        sigma6_return(path(0.01), path(0.0, reachable=False), TOL),
        False,
        "return_reachable = 0",
    ),
    "lift straight up": (lift_plan(0.0, 0.0, path(0.01), 0.2, TOL), True, ""),
    "lift sideways": (lift_plan(0.05, 0.0, path(0.01), 0.2, TOL), False, "sideways_m = 0.05"),
    "lift turned": (lift_plan(0.0, 10.0, path(0.01), 0.2, TOL), False, "turn_deg = 10"),
    "lift collides": (lift_plan(0.0, 0.0, path(-0.01), 0.2, TOL), False, "clearance_m = -0.01"),
    "lift too low": (lift_plan(0.0, 0.0, path(0.01), 0.01, TOL), False, "bottom_clearance_m"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_gate(case: str) -> None:
    verdict, passes, mentioned = CASES[case]
    assert verdict.passed is passes
    assert (verdict.feedback == "") is passes
    assert mentioned in verdict.feedback
    assert set(verdict.measured) == {check.name for check in verdict.checks}


def test_failed_feedback_names_value_and_threshold() -> None:
    verdict = sigma5_placement(aligned(e_xy=0.004, e_theta=2.0), TOL)
    assert verdict.feedback == (
        "sigma5_placement failed: e_xy_m = 0.004, needs <= 0.002; e_theta_deg = 2, needs <= 0.5"
    )


def test_tolerances_refuse_nonsense() -> None:
    with pytest.raises(ValueError, match="greater than 0"):
        Tolerances(c_min_m=-1.0)
    with pytest.raises(ValueError, match="Extra inputs"):
        Tolerances(f_mn_n=5.0)


def test_tolerances_under_noise_widen_what_noisy_sensors_judge() -> None:
    noisy = TOL.under(Sensing(position_std_m=0.002, yaw_std_deg=1.0, force_rel_std=0.1))
    assert noisy.eps_xy_m == pytest.approx(TOL.eps_xy_m + 0.006)
    assert noisy.eps_perp_m == pytest.approx(TOL.eps_perp_m + 0.006)
    assert noisy.eps_theta_deg == pytest.approx(TOL.eps_theta_deg + 3.0)
    assert noisy.eps_g_deg == pytest.approx(TOL.eps_g_deg + 3.0)
    assert noisy.overlap_m == pytest.approx(3.0 * 2**0.5 * 0.002)
    assert noisy.clear(-0.008) and not TOL.clear(-0.001) and not noisy.clear(0.05, reachable=False)
    assert noisy.c_min_m == TOL.c_min_m and noisy.v_th_mps == TOL.v_th_mps
    assert TOL.under(Sensing()) == TOL
