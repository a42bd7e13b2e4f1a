"""Every gate passes and fails on measurements built for the purpose."""

from __future__ import annotations

import json
import math

import pytest

from actionreasoning.agents.feedback import Measured
from actionreasoning.agents.gates import (
    Check,
    GateVerdict,
    creep_limit_mps,
    sigma1_pre_grasp,
    sigma2_descent,
    sigma3_grasp,
    sigma4_lift,
    sigma5_placement,
    sigma6_return,
)
from actionreasoning.agents.plans import lift_plan
from actionreasoning.errors import PatternError
from actionreasoning.tools.collision import CollisionReport
from actionreasoning.tools.contact import ContactForces, SlipEstimate
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.tools.placement import PlacementPose
from actionreasoning.world.models import GoalPattern, Pose, Sensing
from actionreasoning.world.motion import MAX_MOVE_S
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import (
    NOISE_SIGMAS,
    Tolerances,
    joint_share_m,
    opening_slack_m,
    smallest_joint_m,
)

TOL = Tolerances()
NOISY = TOL.under(Sensing(position_std_m=0.002))  # two positions' noise: 8.5 mm of overlap
#: Noisy enough that sigma_5's own offset and height tolerances pass a brick the success
#: rule fails.
VERY_NOISY = TOL.under(Sensing(position_std_m=0.003))
#: Pad forces read with 5 % noise: the friction margin may show a little below zero.
NOISY_FORCES = TOL.under(Sensing(force_rel_std=0.05))
#: A brick up to 20 % heavier and 20 % less grippy than the catalogue says.
UNSURE_BRICK = TOL.under(Sensing(mass_tolerance=0.2, friction_tolerance=0.2))
W = 0.095
MU = 0.6


def path(clearance_m: float, reachable: bool = True) -> CollisionReport:
    return CollisionReport(
        reachable=reachable,
        collision_free=reachable and clearance_m > 0,
        clearance_m=clearance_m,
        closest="gripper_finger_left vs brick 2",
        poses_checked=10,
    )


def required_n(mass_kg: float) -> float:
    """The pad force whose friction carries ``mass_kg`` with mu = MU on both pads."""
    return mass_kg * 9.81 / (2 * MU)


def pads(left: float, right: float, tangential: float = 0.0, mass_kg: float = 1.5) -> ContactForces:
    """Pad forces on a brick of ``mass_kg`` held with mu = 0.6 (pads 1.2 x brick 0.5)."""
    return ContactForces(
        brick_id=0,
        held=left > 1 and right > 1,
        normal_n=(left, right),
        tangential_n=(tangential, tangential),
        friction_coefficient=MU,
        friction_margin_n=MU * (left + right) - 2 * tangential,
        required_normal_n=required_n(mass_kg),
    )


def slip(speed: float, tilt_deg: float = 0.0) -> SlipEstimate:
    return SlipEstimate(
        brick_id=0,
        relative_speed_mps=speed,
        relative_angular_speed_radps=0.0,
        offset_in_gripper_m=(0.0, 0.0, 0.0),
        tilt_in_hand_deg=tilt_deg,
    )


def set_down(
    reachable: bool = True, clearance_m: float = 0.05, tilt_deg: float = 0.0
) -> PlacementPose:
    """The slot pose for the held brick as it sits in the hand (placement_pose's report)."""
    return PlacementPose(
        slot_pose=Pose(position_m=(0.5, 0.0, 0.03), quat_xyzw=(1.0, 0.0, 0.0, 0.0)),
        tilt_in_hand_deg=tilt_deg,
        reachable=reachable,
        way_clearance_m=clearance_m,
        closest="brick 0 vs brick 1",
    )


def aligned(
    e_x: float = 0.0,
    e_theta: float = 0.0,
    d_perp: float = 0.0,
    tilt: float = 0.0,
    e_y: float = 0.0,
) -> AlignmentErrors:
    """A brick set ``e_x``, ``e_y`` short of its target's centre, turned ``e_theta`` short of
    its yaw, ``d_perp`` above its seat and tilted ``tilt``: the success rule's offset and
    rotation follow from them (the rotation taken as the larger of yaw and tilt)."""
    return AlignmentErrors(
        e_xy_m=(e_x, e_y),
        e_xy_norm_m=math.hypot(e_x, e_y),
        e_theta_deg=e_theta,
        d_perp_m=d_perp,
        tilt_deg=tilt,
        rotation_deg=max(abs(e_theta), tilt),
        offset_m=math.hypot(e_x, e_y, d_perp),
    )


def lift(
    sideways: tuple[float, float] = (0.0, 0.0),
    turn: float = 0.0,
    speed: float = 0.01,
    clearance: float = 0.01,
    bottom: float = 0.2,
    tol: Tolerances = TOL,
    rise: float = 0.27,
) -> GateVerdict:
    return lift_plan(sideways, rise, turn, speed, path(clearance), bottom, tol)


#: Just past the sidewall contact threshold, and a light touch well below it.
PRESSING_N = TOL.sidewall_contact_n + 1.0
TOUCHING_N = TOL.sidewall_contact_n / 2.0
NARROW_M = W + TOL.delta_m / 2.0
HEAVY_KG = 6.0  # 49.05 N per pad carries it: more than the pads' 40 N
OFF_XY_M = TOL.eps_xy_m + 0.002
OFF_YAW_DEG = TOL.eps_theta_deg + 0.5

CASES = {
    "sigma1 clear": (sigma1_pre_grasp(path(0.05), TOL), True, ""),
    "sigma1 too close": (sigma1_pre_grasp(path(0.01), TOL), False, "clearance_m = 0.01"),
    "sigma1 unreachable": (sigma1_pre_grasp(path(0.3, reachable=False), TOL), False, "reachable"),
    "sigma2 open": (sigma2_descent(0.16, W, pads(0, 0), (0.0, 0.0), TOL), True, ""),
    "sigma2 open by delta": (
        sigma2_descent(W + TOL.delta_m, W, pads(0, 0), (0.0, 0.0), TOL),
        True,
        "",
    ),
    "sigma2 narrow": (
        sigma2_descent(NARROW_M, W, pads(0, 0), (0.0, 0.0), TOL),
        False,
        f"opening_m = {NARROW_M:.4g}, needs >= {W + TOL.delta_m:.4g}",
    ),
    "sigma2 shoved": (
        sigma2_descent(0.16, W, pads(0, 0), (0.03, 0.0), TOL),
        False,
        "brick_shift_m = 0.03",
    ),
    # 8 mm along each axis is 11.3 mm: more than eps_xy, though neither axis is.
    "sigma2 shoved diagonally": (
        sigma2_descent(0.16, W, pads(0, 0), (0.008, -0.008), TOL),
        False,
        f"brick_shift_m = {math.hypot(0.008, 0.008):.4g}, needs <= {TOL.eps_xy_m:.4g}",
    ),
    "sigma2 shift within eps_xy": (
        sigma2_descent(0.16, W, pads(0, 0), (0.0, TOL.eps_xy_m * 0.9), TOL),
        True,
        "",
    ),
    "sigma2 shift within noise": (
        sigma2_descent(0.16, W, pads(0, 0), (0.02, 0.0), NOISY),
        True,
        "",
    ),
    "sigma2 shift without noise": (
        sigma2_descent(0.16, W, pads(0, 0), (0.02, 0.0), TOL),
        False,
        "brick_shift_m = 0.02",
    ),
    "sigma2 light touch": (
        sigma2_descent(0.16, W, pads(TOUCHING_N, 0), (0.0, 0.0), TOL),
        True,
        "",
    ),
    "sigma2 sidewall": (
        sigma2_descent(0.16, W, pads(PRESSING_N, 0), (0.0, 0.0), TOL),
        False,
        f"sidewall_force_n = {PRESSING_N:.4g}, needs <= {TOL.sidewall_contact_n:.4g}",
    ),
    "sigma3 firm": (sigma3_grasp(pads(40, 38), (0.001, 0.0, 0.0), 0.2, TOL), True, ""),
    "sigma3 weak pad": (
        sigma3_grasp(pads(40, 10), (0.001, 0.0, 0.0), 0.2, TOL),
        False,
        f"normal_force_n = 10, needs >= {TOL.f_min_n(required_n(1.5)):.4g}",
    ),
    # f_min follows the brick: 6 kg x 9.81 / (2 x 0.6) = 49.05 N is more than 40 N.
    "sigma3 heavy brick": (
        sigma3_grasp(pads(40, 40, mass_kg=HEAVY_KG), (0.001, 0.0, 0.0), 0.2, TOL),
        False,
        f"needs >= {TOL.f_min_n(required_n(HEAVY_KG)):.4g}",
    ),
    # A brick that may be 20 % heavier and 20 % less grippy needs 1.5 x the catalogue force.
    "sigma3 unsure brick": (
        sigma3_grasp(pads(40, 20, mass_kg=2.0), (0.001, 0.0, 0.0), 0.2, UNSURE_BRICK),
        False,
        f"normal_force_n = 20, needs >= {UNSURE_BRICK.f_min_n(required_n(2.0)):.4g}",
    ),
    "sigma3 catalogue brick": (
        sigma3_grasp(pads(40, 20, mass_kg=2.0), (0.001, 0.0, 0.0), 0.2, TOL),
        True,
        "",
    ),
    "sigma3 unsure brick held": (
        sigma3_grasp(pads(40, 40, mass_kg=2.0), (0.001, 0.0, 0.0), 0.2, UNSURE_BRICK),
        True,
        "",
    ),
    "sigma3 off pose": (
        sigma3_grasp(pads(110, 110), (0.01, 0.0, 0.0), 0.2, TOL),
        False,
        "pose_error_m = 0.01",
    ),
    # 2.5 mm along each axis is 3.5 mm off: more than eps_g, though neither axis is.
    "sigma3 off pose diagonally": (
        sigma3_grasp(pads(110, 110), (-0.0025, 0.0025, 0.0), 0.2, TOL),
        False,
        f"pose_error_m = {math.hypot(0.0025, 0.0025):.4g}, needs <= {TOL.eps_g_m:.4g}",
    ),
    # A grip that closed 1 cm above the brick's centre (a descent that stopped short).
    "sigma3 high": (
        sigma3_grasp(pads(110, 110), (0.0, 0.0, -0.01), 0.2, TOL),
        False,
        "pose_error_m = 0.01",
    ),
    "sigma3 turned": (
        sigma3_grasp(pads(110, 110), (0.0, 0.0, 0.0), -(TOL.eps_g_deg + 1.0), TOL),
        False,
        f"pose_error_deg = {TOL.eps_g_deg + 1.0:.4g}, needs <= {TOL.eps_g_deg:.4g}",
    ),
    "sigma4 held": (sigma4_lift(slip(0.001), pads(40, 40, 10), set_down(), 0.02, TOL), True, ""),
    "sigma4 slipping": (
        sigma4_lift(slip(0.02), pads(40, 40, 10), set_down(), 0.02, TOL),
        False,
        f"relative_speed_mps = 0.02, needs <= {TOL.v_th_mps:.4g}",
    ),
    # mu (0.6) x 80 N = 48 N of friction carries less than the 60 N the pads hold.
    "sigma4 friction": (
        sigma4_lift(slip(0.0), pads(40, 40, 30), set_down(), 0.02, TOL),
        False,
        "friction_margin_n = -12, needs >= ",
    ),
    # 2 N short of 50 N is within what 5 % force noise can show on 48 N and 50 N.
    "sigma4 friction within force noise": (
        sigma4_lift(slip(0.0), pads(40, 40, 25), set_down(), 0.02, NOISY_FORCES),
        True,
        "",
    ),
    "sigma4 friction without force noise": (
        sigma4_lift(slip(0.0), pads(40, 40, 25), set_down(), 0.02, TOL),
        False,
        "friction_margin_n = -2",
    ),
    "sigma4 dropped": (
        sigma4_lift(slip(0.0), pads(0, 0, 0), set_down(), 0.02, TOL),
        False,
        "normal_force",
    ),
    # No fixed roll limit: a rolled brick passes if it can still be set down level.
    "sigma4 rolled, still settable": (
        sigma4_lift(slip(0.0, tilt_deg=40.0), pads(40, 40, 10), set_down(), 0.02, TOL),
        True,
        "",
    ),
    "sigma4 rolled, set-down out of reach": (
        sigma4_lift(
            slip(0.0, tilt_deg=40.0), pads(40, 40, 10), set_down(reachable=False), 0.02, TOL
        ),
        False,
        "set_down_reachable = 0, needs >= 1",
    ),
    "sigma4 rolled, set-down collides": (
        sigma4_lift(
            slip(0.0, tilt_deg=40.0), pads(40, 40, 10), set_down(clearance_m=-0.004), 0.02, TOL
        ),
        False,
        "set_down_clearance_m = -0.004",
    ),
    "sigma4 set-down within noise": (
        sigma4_lift(slip(0.0), pads(40, 40, 10), set_down(clearance_m=-0.004), 0.02, NOISY),
        True,
        "",
    ),
    "sigma5 aligned": (sigma5_placement(aligned(0.001, 0.2, 0.001), TOL), True, ""),
    "sigma5 offset": (
        sigma5_placement(aligned(e_x=OFF_XY_M), TOL),
        False,
        f"e_xy_m = {OFF_XY_M:.4g}, needs <= {TOL.eps_xy_m:.4g}",
    ),
    "sigma5 turned": (
        sigma5_placement(aligned(e_theta=-OFF_YAW_DEG), TOL),
        False,
        f"e_theta_deg = {OFF_YAW_DEG:.4g}, needs <= {TOL.eps_theta_deg:.4g}",
    ),
    "sigma5 hovering": (
        sigma5_placement(aligned(d_perp=0.01), TOL),
        False,
        f"d_perp_m = 0.01, needs <= {TOL.eps_perp_m:.4g}",
    ),
    "sigma5 tilted": (
        sigma5_placement(aligned(tilt=TOL.eps_tilt_deg + 1.0), TOL),
        False,
        f"tilt_deg = {TOL.eps_tilt_deg + 1.0:.4g}, needs <= {TOL.eps_tilt_deg:.4g}",
    ),
    # Noise widens eps_xy and eps_perp past what the success rule allows together: the rule
    # itself, never widened, still refuses the brick.
    "sigma5 success rule never widened": (
        sigma5_placement(aligned(e_x=0.018, d_perp=0.012), VERY_NOISY),
        False,
        f"offset_m = {math.hypot(0.018, 0.012):.4g}, needs <= {TOL.max_offset_m:.4g}",
    ),
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
    "lift straight up": (lift(), True, ""),
    # 5 cm sideways over a 27 cm rise drags the brick 1.9 mm while it touches its support:
    # a slanted lift the physics allows.
    "lift slanted": (lift(sideways=(0.05, 0.0)), True, ""),
    "lift dragging": (
        lift(sideways=(0.1, 0.0)),
        False,
        f"drag_m = {0.1 * 0.01 / 0.27:.4g}, needs <= {TOL.lift_drag_m:.4g}",
    ),
    # A rise shorter than the support's 1 cm drags the brick all the way.
    "lift short and sideways": (
        lift(sideways=(0.0025, -0.0025), rise=0.005),
        False,
        f"drag_m = {math.hypot(0.0025, 0.0025):.4g}, needs <= {TOL.lift_drag_m:.4g}",
    ),
    "lift turning on the way": (lift(turn=10.0), True, ""),
    "lift twisting": (lift(turn=20.0), False, f"drag_turn_deg = {20 * 0.01 / 0.27:.4g}"),
    "lift at v_lift": (lift(speed=TOL.v_lift_mps), True, ""),
    "lift too fast": (
        lift(speed=2.5 * TOL.v_lift_mps),
        False,
        f"speed_mps = {2.5 * TOL.v_lift_mps:.4g}, needs <= {TOL.v_lift_mps:.4g}",
    ),
    # No duration: as fast as the controller goes, which is no speed a check can pass.
    "lift without a duration": (lift(speed=math.inf), False, "speed_mps = inf"),
    "lift collides": (lift(clearance=-0.01), False, "clearance_m = -0.01"),
    "lift too low": (lift(bottom=0.01), False, "bottom_clearance_m"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_gate(case: str) -> None:
    verdict, passes, mentioned = CASES[case]
    assert verdict.passed is passes
    assert (verdict.feedback == "") is passes
    assert mentioned in verdict.feedback
    refusal = verdict.refusal("some_agent")
    assert refusal.gate == verdict.gate and refusal.agent == "some_agent"
    assert [c.name for c in refusal.failed] == [c.name for c in verdict.checks if not c.passed]
    assert refusal.measured == verdict.measured
    if not passes:
        assert verdict.feedback == refusal.text()
        assert verdict.feedback.startswith(f"{verdict.gate} failed: {refusal.failed[0].name} = ")


#: What each gate measures, signed and in the world frame, "wanted minus measured": a
#: shift or turn of the next answer by it is the correction.
MEASURED = {
    # The brick went (+3, -1) cm on the descent: the grasp must follow it there.
    "sigma2 shove": (
        sigma2_descent(0.16, W, pads(2.0, 0.0), (0.03, -0.01), TOL),
        Measured(e_x_m=0.03, e_y_m=-0.01, pad_forces_n=(2.0, 0.0)),
    ),
    # The brick's centre is 4 mm -x, 2 mm +y of the tool's, turned 3 deg more: move there.
    "sigma3 grip": (
        sigma3_grasp(pads(40, 38), (-0.004, 0.002, 0.0), 3.0, TOL),
        Measured(e_x_m=-0.004, e_y_m=0.002, e_z_m=0.0, e_theta_deg=3.0, pad_forces_n=(40.0, 38.0)),
    ),
    "sigma4 lift": (
        sigma4_lift(slip(0.02, tilt_deg=12.0), pads(40, 40, 10), set_down(), 0.015, TOL),
        Measured(
            tilt_deg=12.0,
            pad_forces_n=(40.0, 40.0),
            slip_speed_mps=0.02,
            move_speed_mps=0.015,
            clearance_m=0.05,
            closest="brick 0 vs brick 1",
        ),
    ),
    # The brick came down 12 mm short along +x and 3 mm past along y, turned 3 deg short.
    "sigma5 miss": (
        sigma5_placement(aligned(e_x=0.012, e_y=-0.003, e_theta=3.0, d_perp=0.001), TOL),
        Measured(e_x_m=0.012, e_y_m=-0.003, e_theta_deg=3.0, d_perp_m=0.001, tilt_deg=0.0),
    ),
    # A lift that drifts (+5, -2) cm: the correction is back the other way.
    "lift drift": (
        lift(sideways=(0.05, -0.02), speed=0.03),
        Measured(
            e_x_m=-0.05,
            e_y_m=0.02,
            move_speed_mps=0.03,
            clearance_m=0.01,
            closest="gripper_finger_left vs brick 2",
        ),
    ),
    "sigma1 path": (
        sigma1_pre_grasp(path(0.01), TOL),
        Measured(clearance_m=0.01, closest="gripper_finger_left vs brick 2"),
    ),
    # Of the two return paths, the one that comes closest is measured.
    "sigma6 worst path": (
        sigma6_return(path(0.04), path(-0.02), TOL),
        Measured(clearance_m=-0.02, closest="gripper_finger_left vs brick 2"),
    ),
}


@pytest.mark.parametrize("case", sorted(MEASURED))
def test_a_gate_measures_signed_world_frame_errors(case: str) -> None:
    verdict, measured = MEASURED[case]
    assert verdict.measured == measured
    refusal = verdict.refusal("agent")
    assert refusal.measured == measured
    if not verdict.passed:
        assert "measured (world frame, wanted minus measured): " in verdict.feedback


def test_failed_feedback_names_value_threshold_and_what_was_measured() -> None:
    verdict = sigma5_placement(aligned(e_x=OFF_XY_M, e_theta=OFF_YAW_DEG), TOL)
    assert verdict.feedback == (
        f"sigma5_placement failed: e_xy_m = {OFF_XY_M:.4g}, needs <= {TOL.eps_xy_m:.4g}; "
        f"e_theta_deg = {OFF_YAW_DEG:.4g}, needs <= {TOL.eps_theta_deg:.4g}; "
        "measured (world frame, wanted minus measured): "
        f"e_x_m={OFF_XY_M:+.5g}, e_y_m=+0, e_theta_deg={OFF_YAW_DEG:+.5g}, d_perp_m=+0, "
        "tilt_deg=+0"
    )


def test_a_noted_verdict_says_what_happened_between_checks_and_measurements() -> None:
    verdict = sigma5_placement(aligned(d_perp=0.01), TOL).noted("the set-down ran to the slot")
    checks, note, measured = verdict.feedback.split("; ")
    assert checks.startswith("sigma5_placement failed: d_perp_m = 0.01")
    assert note == "the set-down ran to the slot"
    assert measured.startswith("measured (world frame, wanted minus measured): e_x_m=+0,")
    assert "d_perp_m=+0.01" in measured
    assert verdict.refusal("placement").note == note


def test_a_check_on_a_value_that_is_not_finite_never_passes() -> None:
    for value in (math.nan, math.inf, -math.inf):
        verdict = sigma3_grasp(pads(40, 40), (value, 0.0, 0.0), 0.0, TOL)
        assert not verdict.passed and "pose_error_m" in verdict.feedback


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
    assert noisy.eps_g_m == pytest.approx(TOL.eps_g_m + 0.006)
    assert noisy.eps_g_deg == pytest.approx(TOL.eps_g_deg + 3.0)
    assert noisy.delta_m == pytest.approx(opening_slack_m(noisy.eps_g_m, noisy.eps_g_deg))
    assert noisy.overlap_m == pytest.approx(3.0 * 2**0.5 * 0.002)
    assert noisy.clear(-0.008) and not TOL.clear(-0.001) and not noisy.clear(0.05, reachable=False)
    # Force noise lowers the force a grip must show and widens the friction margin.
    assert noisy.grip_load_factor == pytest.approx(1.0 - NOISE_SIGMAS * 0.1)
    assert noisy.force_noise == 0.1
    assert noisy.c_min_m == TOL.c_min_m and noisy.v_th_mps == TOL.v_th_mps
    # The success rule's own limits are never widened.
    assert (noisy.max_offset_m, noisy.max_rotation_deg) == (TOL.max_offset_m, TOL.max_rotation_deg)
    assert TOL.under(Sensing()) == TOL


def test_tolerances_for_an_unsure_brick_ask_a_firmer_grip_and_count_on_less_friction() -> None:
    assert UNSURE_BRICK.grip_load_factor == pytest.approx(1.2 / 0.8)
    assert UNSURE_BRICK.friction_factor == pytest.approx(0.8)
    assert UNSURE_BRICK.f_min_n(10.0) == pytest.approx(15.0)


def test_the_design_tolerances_are_the_derived_ones() -> None:
    assert Tolerances.derive() == TOL
    assert TOL.delta_m == pytest.approx(opening_slack_m(TOL.eps_g_m, TOL.eps_g_deg))
    # Half the success rule each: the gates never pass what the rule fails.
    assert TOL.eps_xy_m == pytest.approx(TOL.max_offset_m / 2)
    assert TOL.eps_theta_deg + TOL.eps_tilt_deg == pytest.approx(TOL.max_rotation_deg)


@pytest.fixture(scope="module")
def pyramid() -> GoalPattern:
    return load_pattern("pyramid", SceneSpec())


def test_tolerances_for_a_goal_keep_each_brick_out_of_the_far_half_of_its_joint(
    pyramid: GoalPattern,
) -> None:
    joint = smallest_joint_m(pyramid)
    assert joint is not None and joint > 0.0
    narrowed = TOL.for_goal(pyramid)
    share = joint_share_m(joint, pyramid.brick_size_m[1], TOL.eps_theta_deg)
    assert narrowed.eps_xy_m == pytest.approx(min(TOL.eps_xy_m, share))
    assert narrowed.model_copy(update={"eps_xy_m": TOL.eps_xy_m}) == TOL  # only eps_xy
    one = pyramid.model_copy(update={"targets": pyramid.targets[:1]})
    assert smallest_joint_m(one) is None and TOL.for_goal(one) == TOL


def test_a_threshold_of_minus_zero_is_zero_in_text_and_record() -> None:
    """Minus a zero tolerance (exact sensors) is a threshold of 0, not '-0'."""
    (clearance,) = [
        c
        for c in sigma6_return(path(-0.004), path(0.1), TOL).checks
        if c.name == "retreat_clearance_m"
    ]
    assert TOL.overlap_m == 0.0
    assert math.copysign(1.0, clearance.threshold) == 1.0
    assert clearance.describe().endswith("needs >= 0")
    assert math.copysign(1.0, Check("x", 1.0, -0.0, at_most=False).threshold) == 1.0


def test_a_brick_creeping_faster_than_v_th_is_carried_only_if_it_lasts_the_carry() -> None:
    # The half brick's measured creep at rest (bench/hand_creep.py): 1.76-1.85 mm/s.
    creep = 0.0019
    assert creep > TOL.v_th_mps
    hold_m = TOL.v_th_mps * MAX_MOVE_S
    short, long = 0.5 * hold_m / creep, 2.0 * hold_m / creep
    assert creep_limit_mps(MAX_MOVE_S, TOL) == TOL.v_th_mps  # the longest move: v_th itself
    assert sigma4_lift(slip(creep), pads(40, 40, 10), set_down(), 0.02, TOL, carry_s=short).passed
    refused = sigma4_lift(slip(creep), pads(40, 40, 10), set_down(), 0.02, TOL, carry_s=long)
    assert [c.name for c in refused.checks if not c.passed] == ["relative_speed_mps"]
    # A brick creeping no faster than v_th passes, however long the carry.
    assert sigma4_lift(
        slip(TOL.v_th_mps), pads(40, 40, 10), set_down(), 0.02, TOL, carry_s=MAX_MOVE_S
    ).passed


#: Two full bricks end to end with no joint: a brick turned eps_theta would reach into its
#: neighbour, so no planar tolerance is left (eps_xy would come out -2.07 mm).
TIGHT = {
    "name": "tight",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [
        {"position": [-0.1, 0.0, 0.03], "yaw_deg": 0},
        {"position": [0.1, 0.0, 0.03], "yaw_deg": 0},
    ],
}


def test_a_joint_too_tight_for_the_gates_is_refused_where_it_is_derived(tmp_path) -> None:
    path = tmp_path / "tight.json"
    path.write_text(json.dumps(TIGHT))
    goal = load_pattern(path, SceneSpec())
    with pytest.raises(PatternError) as refused:
        TOL.for_goal(goal)
    least = 0.095 * math.sin(math.radians(TOL.eps_theta_deg))  # 4.1 mm: joint / 2 > that / 2
    assert str(refused.value) == (
        "pattern 'tight': the joint between targets 0 and 1 is 0.0 mm; the agents' gates need "
        f"joints wider than {least * 1000:.1f} mm (a brick turned 2.5 deg must stay out of its "
        "joint's far half)"
    )
