"""Tolerances: every threshold of the gates sigma_1..sigma_6, in one place, with defaults."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


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
    f_min_n: float = Field(50.0, gt=0, description="sigma_3: least normal force on each pad.")
    eps_g_m: float = Field(0.003, gt=0, description="sigma_3: tool position error at the grasp.")
    eps_g_deg: float = Field(1.0, gt=0, description="sigma_3: tool orientation error at grasp.")
    v_th_mps: float = Field(
        0.005, gt=0, description="sigma_4: largest brick speed relative to the gripper."
    )
    eps_perp_m: float = Field(
        0.002, gt=0, description="sigma_5: largest height of the brick's bottom above its seat."
    )
    eps_xy_m: float = Field(0.002, gt=0, description="sigma_5: largest planar offset.")
    eps_theta_deg: float = Field(0.5, gt=0, description="sigma_5: largest yaw error.")
    delta_h_m: float = Field(0.01, gt=0, description="sigma_5 = 0 in contact: raise by this.")
