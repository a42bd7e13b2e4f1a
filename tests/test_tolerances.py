"""Every gate threshold recomputed from its inputs (the success rule, the catalogue brick,
the gripper, the arm's reach, the measured physics, the sensing noise, the pattern's
joints), and the gates never pass what the success rule fails."""

from __future__ import annotations

import math

import pytest
from conftest import DOCS

from actionreasoning.agents.gates import sigma5_placement
from actionreasoning.agents.plans import Grip
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import Tolerances, derivation_table, derivations

#: The inputs, written out: brick 0.20 x 0.095 x 0.06 m, 1.5 kg; success 2 cm, 5 deg;
#: fingertips 2 cm below the tool centre, pads 4 cm long; reach 0.76 m; joint checks every
#: 0.05 rad; moves at most 30 s; measured: path deviation 3 mm, grasp error 2 mm / 0.5 deg
#: (rounded up), safe lift 2 cm/s; brick-on-ground friction 0.5.
L, W, H, MASS, G = 0.20, 0.095, 0.06, 1.5, 9.81
OFFSET, TURN = 0.02, 5.0


def test_each_design_threshold_follows_from_its_inputs() -> None:
    t = Tolerances()
    assert t == Tolerances.derive()
    assert t.c_min_m == pytest.approx(0.05 * 0.76 / 2 + 0.003)
    assert t.eps_g_m == 0.002 and t.eps_g_deg == 0.5
    assert t.delta_m == pytest.approx(2 * 0.002 + 0.04 * math.sin(math.radians(0.5)))
    assert t.sidewall_contact_n == pytest.approx(0.5 * MASS * G)
    assert (t.grip_load_factor, t.friction_factor, t.force_noise) == (1.0, 1.0, 0.0)
    assert t.v_th_mps == pytest.approx((H / 2 + 0.02) / 30.0)
    assert t.v_lift_mps == 0.02
    assert t.eps_perp_m == pytest.approx(L / 2 * math.tan(math.radians(TURN / 2)))
    assert t.eps_xy_m == pytest.approx(OFFSET / 2)
    assert t.eps_theta_deg == t.eps_tilt_deg == pytest.approx(TURN / 2)
    assert (t.max_offset_m, t.max_rotation_deg) == (OFFSET, TURN)
    assert t.delta_h_m == pytest.approx(2 * t.eps_perp_m)
    assert t.overlap_m == 0.0
    assert [row.name for row in derivations()] == list(Tolerances.model_fields)


def test_each_pre_move_tolerance_follows_from_its_inputs() -> None:
    """The pre-move checks' own thresholds (agents/plans.py): the approach keeps sigma_1's
    clearance from the brick its path check leaves out; the pads need room of no less than
    zero (more under noise, the brick's place being uncertain); a lift drags the brick no
    further, and twists it no more, than the grip's own measured error."""
    t = Tolerances()
    assert t.hover_clearance_m == t.c_min_m == pytest.approx(0.05 * 0.76 / 2 + 0.003)
    assert t.pad_room_m == 0.0
    assert (t.lift_drag_m, t.lift_drag_deg) == (0.002, 0.5)
    noisy = t.under(NOISE["medium"].sensing())
    position = 3 * NOISE["medium"].perception.position_std_m
    assert noisy.pad_room_m == pytest.approx(position)
    assert (noisy.lift_drag_m, noisy.lift_drag_deg) == (0.002, 0.5)  # against the tool itself
    assert noisy.hover_clearance_m == t.hover_clearance_m


def test_the_opening_delta_leaves_the_pads_no_room_at_the_grip_tolerance() -> None:
    """delta (sigma_2) and the pads' room (the pre-move checks) are one geometry: an opening
    of width + delta passes the side walls with the tool eps_g off across the brick and
    turned eps_g_deg, with nothing to spare."""
    t = Tolerances()
    grip = Grip(
        along_m=0.0,
        across_m=t.eps_g_m,
        up_m=0.0,
        yaw_deg=t.eps_g_deg,
        tilt_deg=0.0,
        world_offset_m=(0.0, t.eps_g_m, 0.0),
    )
    assert grip.pad_room_m(W + t.delta_m, W) == pytest.approx(0.0, abs=1e-5)
    assert grip.pad_room_m(W + t.delta_m + 0.002, W) == pytest.approx(0.001, abs=1e-5)


def test_a_stricter_success_rule_makes_stricter_gates() -> None:
    strict = Tolerances.derive(SuccessRule(max_center_offset_cm=1.0, max_rotation_error_deg=2.0))
    assert strict.eps_xy_m == pytest.approx(0.005)
    assert strict.eps_theta_deg == strict.eps_tilt_deg == pytest.approx(1.0)
    assert strict.eps_perp_m == pytest.approx(L / 2 * math.tan(math.radians(1.0)))
    assert (strict.max_offset_m, strict.max_rotation_deg) == (0.01, 2.0)


@pytest.mark.parametrize("level", list(NOISE))
def test_noise_widens_what_compares_measurements_and_never_the_success_rule(level: str) -> None:
    noise = NOISE[level]
    p, v = noise.perception, noise.variation
    t = Tolerances().under(noise.sensing())
    d = Tolerances()
    position, yaw = 3 * p.position_std_m, 3 * p.yaw_std_deg
    assert t.eps_g_m == pytest.approx(d.eps_g_m + position)
    assert t.eps_g_deg == pytest.approx(d.eps_g_deg + yaw)
    assert t.delta_m == pytest.approx(
        2 * (d.eps_g_m + position) + 0.04 * math.sin(math.radians(d.eps_g_deg + yaw))
    )
    assert t.eps_perp_m == pytest.approx(d.eps_perp_m + position)
    assert t.eps_xy_m == pytest.approx(d.eps_xy_m + position)
    assert t.eps_theta_deg == pytest.approx(d.eps_theta_deg + yaw)
    assert t.overlap_m == pytest.approx(math.sqrt(2) * position)
    worst = (1 + v.mass_rel) / (1 - v.friction_rel) * (1 - 3 * p.force_rel_std)
    assert t.grip_load_factor == pytest.approx(max(0.0, worst))
    assert t.friction_factor == pytest.approx(1 - v.friction_rel)
    assert t.force_noise == p.force_rel_std
    # Velocities and tilt are measured without noise; the success rule is never widened.
    for name in ("v_th_mps", "v_lift_mps", "eps_tilt_deg", "max_offset_m", "max_rotation_deg"):
        assert getattr(t, name) == getattr(d, name), name


def test_a_pattern_with_narrow_joints_narrows_the_planar_offset() -> None:
    spec = SceneSpec()
    grid, pyramid = load_pattern("grid", spec), load_pattern("pyramid", spec)
    share = 0.02 / 2 - W / 2 * math.sin(math.radians(TURN / 2))  # the grid's 2 cm joints
    assert Tolerances().for_goal(grid).eps_xy_m == pytest.approx(share)
    assert Tolerances().for_goal(pyramid).eps_xy_m == pytest.approx(OFFSET / 2)  # 5 cm joints
    one = pyramid.model_copy(update={"targets": pyramid.targets[:1]})
    assert Tolerances().for_goal(one) == Tolerances()


def _alignment(e_xy: float, d_perp: float, e_theta: float, tilt: float) -> AlignmentErrors:
    return AlignmentErrors(
        e_xy_m=(e_xy, 0.0),
        e_xy_norm_m=e_xy,
        e_theta_deg=e_theta,
        d_perp_m=d_perp,
        tilt_deg=tilt,
        rotation_deg=math.hypot(e_theta, tilt),
        offset_m=math.hypot(e_xy, d_perp),
    )


@pytest.mark.parametrize("level", list(NOISE))
def test_sigma5_never_passes_what_the_success_rule_fails(level: str) -> None:
    t = Tolerances().under(NOISE[level].sensing())
    refused = 0
    for e_xy in (0.0, 0.005, 0.01, 0.015, 0.019, 0.021, 0.03):
        for d_perp in (0.0, 0.004, 0.008, 0.012, 0.016):
            for e_theta in (0.0, 2.0, 4.0, 4.9, 6.0):
                for tilt in (0.0, 1.0, 2.4, 3.0):
                    measured = _alignment(e_xy, d_perp, e_theta, tilt)
                    beyond = measured.offset_m > OFFSET or measured.rotation_deg > TURN
                    if beyond:
                        assert not sigma5_placement(measured, t).passed, measured
                        refused += 1
    assert refused > 0
    # A set-down well inside every tolerance passes.
    assert sigma5_placement(_alignment(0.001, 0.001, 0.2, 0.2), t).passed


def test_the_docs_show_the_derivation_table() -> None:
    goal = load_pattern("pyramid", SceneSpec())
    run = Tolerances().for_goal(goal).under(NOISE["medium"].sensing())
    assert derivation_table(run, "pyramid, noise medium") in (DOCS / "conditions.md").read_text()
