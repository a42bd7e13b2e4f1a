"""Tolerances: every threshold of the gates sigma_1..sigma_6, in one place, with defaults.

Thresholds that physics defines are not constants: the pad force a grasp needs comes from
the brick's mass and friction (``ContactForces.required_normal_n``) times a safety factor,
and the friction margin from the measured forces and mu. Geometric thresholds that noisy
sensors judge are widened by three standard deviations of that noise (:meth:`under`).
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.world.models import Sensing

#: Standard deviations of sensing noise a geometric threshold is widened by.
NOISE_SIGMAS = 3.0


class Tolerances(BaseModel):
    """Gate thresholds (paper section III-C). Lengths in metres, forces in newtons."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    c_min_m: float = Field(0.02, gt=0, description="sigma_1: least clearance of a transit path.")
    delta_m: float = Field(
        0.03, gt=0, description="sigma_2: opening beyond the brick's width (both sides together)."
    )
    sidewall_contact_n: float = Field(
        1.0, gt=0, description="sigma_2: a pad force above this is contact with a side wall."
    )
    grip_safety_factor: float = Field(
        2.0,
        ge=1.0,
        description="sigma_3, sigma_4: each pad must press with this many times the force whose "
        "friction carries the brick's weight, m g / (2 mu), from its catalogue mass and friction",
    )
    eps_g_m: float = Field(0.003, gt=0, description="sigma_3: tool position error at the grasp.")
    eps_g_deg: float = Field(1.0, gt=0, description="sigma_3: tool orientation error at grasp.")
    v_th_mps: float = Field(
        0.005, gt=0, description="sigma_4: largest brick speed relative to the gripper."
    )
    eps_tilt_deg: float = Field(
        20.0,
        gt=0,
        description="sigma_4: largest roll of the brick in the hand; placement sets a brick "
        "rolled this far level by tilting the tool, a brick rolled further is grasped again.",
    )
    eps_perp_m: float = Field(
        0.002, gt=0, description="sigma_5: largest height of the brick's bottom above its seat."
    )
    eps_xy_m: float = Field(0.002, gt=0, description="sigma_5: largest planar offset.")
    eps_theta_deg: float = Field(0.5, gt=0, description="sigma_5: largest yaw error.")
    delta_h_m: float = Field(0.01, gt=0, description="sigma_5 = 0 in contact: raise by this.")
    overlap_m: float = Field(
        0.0,
        ge=0,
        description="Largest overlap of two measured bodies a path check still calls clear: "
        "none for exact sensors; under noise, what the noise of two positions can show.",
    )

    def clear(self, clearance_m: float, reachable: bool = True) -> bool:
        """Whether a path with this clearance counts as collision-free."""
        return reachable and clearance_m > -self.overlap_m

    def under(self, sensing: Sensing) -> Tolerances:
        """These thresholds as judged through noisy sensors: each geometric one widened by
        NOISE_SIGMAS standard deviations of the noise of what it compares, so that a gate
        judges the world and not the noise (unchanged without noise)."""
        position = NOISE_SIGMAS * sensing.position_std_m
        yaw = NOISE_SIGMAS * sensing.yaw_std_deg
        return self.model_copy(
            update={
                "eps_g_m": self.eps_g_m + position,
                "eps_g_deg": self.eps_g_deg + yaw,
                "eps_perp_m": self.eps_perp_m + position,
                "eps_xy_m": self.eps_xy_m + position,
                "eps_theta_deg": self.eps_theta_deg + yaw,
                "overlap_m": self.overlap_m + math.sqrt(2.0) * position,
            }
        )
