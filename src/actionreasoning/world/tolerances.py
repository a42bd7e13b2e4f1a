"""Tolerances: every threshold of the gates, each derived from what it protects.

A threshold protects the success rule (2 cm, 5 deg: a gate must never pass what the rule
fails), what the next course needs to seat, or the grip (the brick's mass and friction);
sensing noise widens what compares two measurements by NOISE_SIGMAS standard deviations, so that a
gate judges the world, not the noise. :func:`derivations` gives each value with its formula (the
table of docs/conditions.md, ``actionreasoning tolerances``); the design values come from
:meth:`Tolerances.derive`, the values a trial runs under from :meth:`Tolerances.under` (sensing
noise, announced mass and friction tolerances) and :meth:`Tolerances.for_goal` (the pattern's
joints).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydantic import BaseModel, ConfigDict, Field
from shapely.geometry import Polygon

from actionreasoning.errors import PatternError
from actionreasoning.world.boxes import Box
from actionreasoning.world.clearance import JOINT_STEP_RAD
from actionreasoning.world.models import GoalPattern, Sensing
from actionreasoning.world.motion import MAX_MOVE_S
from actionreasoning.world.scene_spec import (
    FINGERTIPS_BEYOND_TCP_M,
    PAD_LENGTH_M,
    SceneSpec,
)
from actionreasoning.world.success import SuccessRule

#: Standard deviations of sensing noise a threshold that compares measurements is widened by.
NOISE_SIGMAS = 3.0
#: Measured under paper physics (``bench/lift_roll.py``): the fastest of the lift speeds
#: tried (1, 2, 3, 5, 10 cm/s and the controller's limit, 16 grasps each) at which no
#: brick rolled more than 10 deg in the hand.
SAFE_LIFT_MPS = 0.02
#: Measured under paper physics (``bench/grasp_error.py``, 120 grasps, no noise): the largest
#: tool-to-brick error a grip leaves when the pads close on a brick at rest, 1.3 mm and
#: 0.25 deg, rounded up to the millimetre and the half degree.
GRASP_ERROR_M = 0.002
GRASP_ERROR_DEG = 0.5
#: Measured (``bench/path_deviation.py``, 2 agents trials): the largest distance of the tool
#: from the path it was planned along, 2.8 mm, rounded up to the millimetre.
PATH_DEVIATION_M = 0.003
#: Below this rise a lifted brick still touches its support (its bottom's unevenness and
#: the pads' give): the lift checks a path from here up, and bounds the tool's drag below it.
LIFT_SUPPORT_M = 0.01
#: Brick-on-ground friction the sidewall threshold is measured against: the brick's own
#: (paper physics' default lateral friction) times the ground's (plane.urdf's 1.0).
GROUND_FRICTION = 0.5
GRAVITY = 9.81


def opening_slack_m(eps_g_m: float, eps_g_deg: float) -> float:
    """The opening beyond a brick's width that lets the pads pass both its side walls when
    the tool is off by the grasp tolerance on each side and turned by its yaw tolerance
    (the pads, PAD_LENGTH_M long, then meet the brick's width slanted)."""
    return 2.0 * eps_g_m + PAD_LENGTH_M * math.sin(math.radians(eps_g_deg))


def grip_load_factor(sensing: Sensing) -> float:
    """How many times the catalogue brick's required pad force a grip must show: the
    heaviest brick over the least friction the tolerances allow, read through force noise
    of NOISE_SIGMAS standard deviations (never below zero)."""
    worst = (1.0 + sensing.mass_tolerance) / (1.0 - sensing.friction_tolerance)
    return max(0.0, worst * (1.0 - NOISE_SIGMAS * sensing.force_rel_std))


def joint_share_m(joint_m: float, width_m: float, eps_theta_deg: float) -> float:
    """The planar offset that keeps a brick's corner, turned by up to ``eps_theta_deg``, out
    of the far half of a joint ``joint_m`` wide."""
    return joint_m / 2.0 - width_m / 2.0 * math.sin(math.radians(eps_theta_deg))


def smallest_joint_m(goal: GoalPattern) -> float | None:
    """The narrowest gap between two bricks of one course of ``goal`` (None: no course holds
    two bricks)."""
    joint = narrowest_joint(goal)
    return None if joint is None else joint[0]


def narrowest_joint(goal: GoalPattern) -> tuple[float, int, int] | None:
    """The narrowest gap between two bricks of one course of ``goal`` and the two targets'
    indices (None: no course holds two bricks)."""
    courses: dict[int, list[tuple[int, Polygon]]] = {}
    for target in goal.targets:
        footprint = Box(target.pose.position_m, target.pose.quat_xyzw, target.size_m).footprint
        courses.setdefault(round(target.pose.position_m[2] * 1000), []).append(
            (target.index, footprint)
        )
    gaps = [
        (a.distance(b), i, j)
        for course in courses.values()
        for k, (i, a) in enumerate(course)
        for j, b in course[k + 1 :]
    ]
    return min(gaps, default=None)


@dataclass(frozen=True)
class Derivation:
    """One threshold: its value, what it protects and how it follows from its inputs."""

    name: str
    value: float
    unit: str
    protects: str
    formula: str


def derivations(
    rule: SuccessRule = SuccessRule(), scene: SceneSpec = SceneSpec()
) -> list[Derivation]:
    """Every design threshold with its derivation, in the order of the gates."""
    return _design(rule, scene)


def derivation_table(run: Tolerances, condition: str) -> str:
    """A Markdown table of every threshold: its design value, its value in a trial run
    under ``run`` (described by ``condition``), what it protects and how it is derived."""
    values = run.model_dump()
    lines = [
        f"| threshold | design value | {condition} | protects | derivation |",
        "|---|---|---|---|---|",
    ]
    for row in derivations():
        unit = f" {row.unit}" if row.unit else ""
        lines.append(
            f"| `{row.name}` | {row.value:.4g}{unit} | {values[row.name]:.4g}{unit} "
            f"| {row.protects} | {row.formula} |"
        )
    return "\n".join(lines) + "\n"


def _design(rule: SuccessRule, scene: SceneSpec) -> list[Derivation]:
    length, _, height = scene.brick_size_m
    offset = rule.max_center_offset_cm / 100.0
    turn = rule.max_rotation_error_deg
    half_turn = turn / 2.0
    seat = length / 2.0 * math.tan(math.radians(half_turn))
    weight = scene.brick_mass_kg * GRAVITY
    c_min = JOINT_STEP_RAD * scene.reach.max_radius_m / 2.0 + PATH_DEVIATION_M
    return [
        Derivation(
            "c_min_m",
            c_min,
            "m",
            "sigma_1, lift: a path between the poses its check samples",
            f"half the tool's travel between two poses a joint path check samples, "
            f"{JOINT_STEP_RAD} rad x reach {scene.reach.max_radius_m} m / 2, + the tool's "
            f"largest measured deviation from its planned path, {PATH_DEVIATION_M} m",
        ),
        Derivation(
            "delta_m",
            opening_slack_m(GRASP_ERROR_M, GRASP_ERROR_DEG),
            "m",
            "sigma_2: the pads pass the side walls",
            f"2 eps_g_m + pad length {PAD_LENGTH_M} m x sin(eps_g_deg), from eps_g as widened",
        ),
        Derivation(
            "sidewall_contact_n",
            GROUND_FRICTION * weight,
            "N",
            "sigma_2: the brick is not shoved before the grip closes",
            f"the force that slides the brick over the ground: friction {GROUND_FRICTION} x "
            f"{scene.brick_mass_kg} kg x g; under noise for the lightest, least grippy brick, "
            "read through 3 x force noise",
        ),
        Derivation(
            "grip_load_factor",
            1.0,
            "",
            "sigma_3, sigma_4: the grip carries the brick",
            "(1 + mass tolerance) / (1 - friction tolerance) x (1 - 3 force noise): 1 "
            "for exact sensors and catalogue bricks",
        ),
        Derivation(
            "friction_factor",
            1.0,
            "",
            "sigma_4: friction margin",
            "1 - friction tolerance: the least friction a brick may have",
        ),
        Derivation(
            "eps_g_m",
            GRASP_ERROR_M,
            "m",
            "sigma_3: a grip centred on the brick; before the approach, the descent and a "
            "corrected grasp, the forecast of sigma_3 on the pose asked for",
            "the largest centre error a grip closing on a brick at rest left, 1.3 mm in 120 "
            "grasps, rounded up; + 3 x position noise. The forecast compares the pose's offset "
            "along the brick's length and in height (the closing centres it across its width: "
            "pad_room_m) with the same threshold, since the grip closes where the tool is",
        ),
        Derivation(
            "eps_g_deg",
            GRASP_ERROR_DEG,
            "deg",
            "sigma_3: pads flat on the brick; the forecast of sigma_3 before the approach, "
            "the descent and a corrected grasp; a grasp from above",
            "the largest yaw error a closing grip left, 0.25 deg in 120 grasps, rounded up; "
            "+ 3 x yaw noise. The closing does not turn the brick (a grasp 3, 6 or 10 deg off "
            "keeps 90 % of it: bench/grip_centring.py), so the forecast compares the pose's yaw "
            "with the same threshold; and the tool points down within it (the pads close level "
            "on the vertical side walls)",
        ),
        Derivation(
            "hover_clearance_m",
            c_min,
            "m",
            "pre-grasp: the approach hovers clear of the brick it is over",
            "c_min_m: the clearance sigma_1 asks of every other body, kept from the brick its "
            "path check leaves out (the descent goes to it), fingertips to the brick's top",
        ),
        Derivation(
            "pad_room_m",
            0.0,
            "m",
            "pre-grasp, descent, a corrected grasp: the open pads pass outside both side "
            "walls, so the closing centres the brick across its width",
            "0: the least room between a pad and the side wall it passes, on the straight way "
            "down from where the fingertips reach the brick's top to the grasp (half the "
            "opening - the tool's offset across the width - width / 2 / cos(yaw error) - pad "
            "length / 2 x |tan(yaw error)|); + 3 x position noise. The closing centres a brick "
            "up to 15 mm off across its width to 0.5 mm (bench/grip_centring.py)",
        ),
        Derivation(
            "v_th_mps",
            (height / 2.0 + FINGERTIPS_BEYOND_TCP_M) / MAX_MOVE_S,
            "m/s",
            "sigma_4: the brick stays in the hand until it is measured again",
            f"(brick height / 2 + fingertips {FINGERTIPS_BEYOND_TCP_M} m below the tool "
            f"centre) / the longest move, {MAX_MOVE_S:g} s",
        ),
        Derivation(
            "v_lift_mps",
            SAFE_LIFT_MPS,
            "m/s",
            "lift: the brick leaves its support level",
            "the fastest of the lift speeds measured at which no brick of 16 rolled more "
            "than 10 deg in the hand",
        ),
        Derivation(
            "lift_drag_m",
            GRASP_ERROR_M,
            "m",
            "lift: the brick breaks away from its support without being dragged in the hand",
            f"the grip's own largest measured error, {GRASP_ERROR_M} m: the tool's sideways "
            f"travel while the brick still touches its support (the lift's first "
            f"{LIFT_SUPPORT_M} m of rise) moves the brick in the hand no further than the grip "
            "already is off; measured against the tool, so not widened for noise",
        ),
        Derivation(
            "lift_drag_deg",
            GRASP_ERROR_DEG,
            "deg",
            "lift: the brick breaks away from its support without being twisted in the hand",
            f"the grip's largest measured yaw error, {GRASP_ERROR_DEG} deg: the turn the "
            f"tool makes over the lift's first {LIFT_SUPPORT_M} m of rise",
        ),
        Derivation(
            "force_noise",
            0.0,
            "",
            "sigma_4: friction margin read through noisy forces",
            "the pad forces' relative noise (std) the sensors announce: 0 when exact; the "
            "margin may then show down to -3 x this x the forces compared",
        ),
        Derivation(
            "eps_perp_m",
            seat,
            "m",
            "sigma_5: the next course's seat",
            f"a brick bridging two seats half its length ({length / 2:g} m) apart tilts by "
            f"at most half the success rule's rotation: {length / 2:g} x tan({half_turn:g} deg); "
            "+ 3 x position noise",
        ),
        Derivation(
            "eps_xy_m",
            offset / 2.0,
            "m",
            "sigma_5: success rule; the next brick of the row",
            f"half the success rule's {offset:g} m (the other half for the height and the "
            "release); for a pattern, also the narrowest joint / 2 - width / 2 x "
            "sin(eps_theta_deg); + 3 x position noise",
        ),
        Derivation(
            "eps_theta_deg",
            half_turn,
            "deg",
            "sigma_5: success rule",
            f"half the success rule's {turn:g} deg (the other half for the tilt); + 3 x yaw noise",
        ),
        Derivation(
            "eps_tilt_deg",
            half_turn,
            "deg",
            "sigma_5: success rule",
            f"half the success rule's {turn:g} deg (the other half for the yaw); tilt is "
            "measured without noise",
        ),
        Derivation(
            "max_offset_m",
            offset,
            "m",
            "sigma_5: success rule, never widened",
            "the success rule's centre offset",
        ),
        Derivation(
            "max_rotation_deg",
            turn,
            "deg",
            "sigma_5: success rule, never widened",
            "the success rule's rotation error",
        ),
        Derivation(
            "delta_h_m",
            2.0 * seat,
            "m",
            "sigma_5 = 0: the raise clears the seat",
            "2 eps_perp_m: a brick up to eps_perp_m above its seat rises as far again clear",
        ),
        Derivation(
            "overlap_m",
            0.0,
            "m",
            "path checks: judge the world, not the noise",
            "sqrt(2) x 3 position noise: what two noisy positions can show",
        ),
    ]


_DEFAULTS = {row.name: row.value for row in _design(SuccessRule(), SceneSpec())}


class Tolerances(BaseModel):
    """Gate thresholds (paper section III-C). Lengths in metres, forces in newtons; the
    defaults are :meth:`derive`'s for the default success rule and the catalogue brick."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    c_min_m: float = Field(
        _DEFAULTS["c_min_m"],
        gt=0,
        description="least clearance along a path.",
    )
    delta_m: float = Field(
        _DEFAULTS["delta_m"],
        gt=0,
        description="least opening beyond the brick's width to descend.",
    )
    sidewall_contact_n: float = Field(
        _DEFAULTS["sidewall_contact_n"],
        gt=0,
        description="a pad force above this going down touches a wall.",
    )
    grip_load_factor: float = Field(
        _DEFAULTS["grip_load_factor"],
        ge=0.0,
        description="each pad presses with at least this many times the force whose "
        "friction carries the brick's weight.",
    )
    friction_factor: float = Field(
        _DEFAULTS["friction_factor"],
        gt=0,
        le=1.0,
        description="share of the catalogue friction counted on.",
    )
    eps_g_m: float = Field(
        _DEFAULTS["eps_g_m"],
        gt=0,
        description="largest offset of a grip from the brick's centre.",
    )
    eps_g_deg: float = Field(
        _DEFAULTS["eps_g_deg"],
        gt=0,
        description="largest yaw of a grip from the brick's.",
    )
    hover_clearance_m: float = Field(
        _DEFAULTS["hover_clearance_m"],
        gt=0,
        description="least height of the fingertips over the brick at the approach.",
    )
    pad_room_m: float = Field(
        _DEFAULTS["pad_room_m"],
        ge=0,
        description="least room between an open pad and a side wall going down.",
    )
    v_th_mps: float = Field(
        _DEFAULTS["v_th_mps"],
        gt=0,
        description="largest speed of the brick in the hand.",
    )
    v_lift_mps: float = Field(
        _DEFAULTS["v_lift_mps"],
        gt=0,
        description="largest mean speed of a lift.",
    )
    lift_drag_m: float = Field(
        _DEFAULTS["lift_drag_m"],
        gt=0,
        description="largest sideways travel over a lift's first 1 cm.",
    )
    lift_drag_deg: float = Field(
        _DEFAULTS["lift_drag_deg"],
        gt=0,
        description="largest turn over a lift's first 1 cm.",
    )
    force_noise: float = Field(
        0.0, ge=0.0, description="relative noise (std) of a pad force reading."
    )
    eps_perp_m: float = Field(
        _DEFAULTS["eps_perp_m"],
        gt=0,
        description="largest height of a set brick over its seat.",
    )
    eps_xy_m: float = Field(
        _DEFAULTS["eps_xy_m"],
        gt=0,
        description="largest planar offset of a set brick.",
    )
    eps_theta_deg: float = Field(
        _DEFAULTS["eps_theta_deg"], gt=0, description="largest yaw error of a set brick."
    )
    eps_tilt_deg: float = Field(
        _DEFAULTS["eps_tilt_deg"], gt=0, description="largest tilt of a set brick."
    )
    max_offset_m: float = Field(
        _DEFAULTS["max_offset_m"],
        gt=0,
        description="success rule: largest centre offset.",
    )
    max_rotation_deg: float = Field(
        _DEFAULTS["max_rotation_deg"],
        gt=0,
        description="success rule: largest rotation.",
    )
    delta_h_m: float = Field(
        _DEFAULTS["delta_h_m"],
        gt=0,
        description="raise after a missed set-down.",
    )
    overlap_m: float = Field(
        _DEFAULTS["overlap_m"],
        ge=0,
        description="largest overlap still counted as clear (sensing noise).",
    )

    @classmethod
    def derive(
        cls, rule: SuccessRule = SuccessRule(), scene: SceneSpec = SceneSpec()
    ) -> Tolerances:
        """The design values: derived from the success rule, the catalogue brick and the
        gripper, for exact sensors and any pattern (see :func:`derivations`)."""
        return cls(**{row.name: row.value for row in _design(rule, scene)})

    def clear(self, clearance_m: float, reachable: bool = True) -> bool:
        """Whether a path with this clearance counts as collision-free."""
        return reachable and clearance_m > -self.overlap_m

    def f_min_n(self, required_normal_n: float) -> float:
        """The least pad force sigma_3 and sigma_4 accept for a brick whose catalogue weight
        needs ``required_normal_n`` per pad."""
        return self.grip_load_factor * required_normal_n

    def under(self, sensing: Sensing) -> Tolerances:
        """These thresholds as judged through noisy sensors: each that compares measured
        positions or yaws widened by NOISE_SIGMAS standard deviations of their noise, the
        grip's by the announced mass and friction tolerances and the force noise
        (unchanged without noise). The success rule's own limits are never widened."""
        position = NOISE_SIGMAS * sensing.position_std_m
        yaw = NOISE_SIGMAS * sensing.yaw_std_deg
        eps_g_m, eps_g_deg = self.eps_g_m + position, self.eps_g_deg + yaw
        return self.model_copy(
            update={
                "eps_g_m": eps_g_m,
                "eps_g_deg": eps_g_deg,
                "delta_m": opening_slack_m(eps_g_m, eps_g_deg),
                "pad_room_m": self.pad_room_m + position,
                "eps_perp_m": self.eps_perp_m + position,
                "eps_xy_m": self.eps_xy_m + position,
                "eps_theta_deg": self.eps_theta_deg + yaw,
                "overlap_m": self.overlap_m + math.sqrt(2.0) * position,
                "sidewall_contact_n": self.sidewall_contact_n
                * (1.0 - sensing.mass_tolerance)
                * (1.0 - sensing.friction_tolerance)
                * (1.0 + NOISE_SIGMAS * sensing.force_rel_std),
                "grip_load_factor": grip_load_factor(sensing),
                "force_noise": sensing.force_rel_std,
                "friction_factor": 1.0 - sensing.friction_tolerance,
            }
        )

    def for_goal(self, goal: GoalPattern) -> Tolerances:
        """These thresholds for building ``goal``: the planar offset also keeps each brick out
        of the far half of the narrowest joint between two bricks of a course."""
        narrowest = narrowest_joint(goal)
        if narrowest is None:
            return self
        joint, a, b = narrowest
        width = goal.brick_size_m[1]
        share = joint_share_m(joint, width, self.eps_theta_deg)
        if share <= 0.0:
            # joint / 2 > width / 2 * sin(eps_theta): the least joint the gates work with.
            least = width * math.sin(math.radians(self.eps_theta_deg))
            raise PatternError(
                f"pattern '{goal.name}': the joint between targets {a} and {b} is "
                f"{joint * 1000:.1f} mm; the agents' gates need joints wider than "
                f"{least * 1000:.1f} mm (a brick turned {self.eps_theta_deg:g} deg must stay out "
                "of its joint's far half)"
            )
        return self.model_copy(update={"eps_xy_m": min(self.eps_xy_m, share)})
