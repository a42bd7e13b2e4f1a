"""Physics profiles: the simulator settings a trial runs under, named and recorded.

Two built-ins (``--physics paper|precise``, registered in ``scenarios.py``) and a file form
(JSON/YAML, the fields of :class:`PhysicsProfile`). A profile has three parts:

* the engine: time step, solver iterations, contact breaking threshold, friction anchors;
* the contact properties of the bricks and the ground;
* our gripper and arm drive (pad friction, grip force limit, finger speed, joint force).
  These are our design, the same in both built-ins, as pybullet_data's KUKA gripper asset
  sets its own finger friction.

``paper`` is PyBullet's own defaults for the first two parts, as a fresh client reports
them (``getPhysicsEngineParameters``, ``getDynamicsInfo`` of a new box and of
``plane.urdf``; the contact breaking threshold, which no call reports, is Bullet's
``gContactBreakingThreshold``): the paper's experiments ran under "simulator defaults".
``precise`` is the setting tuned until nothing slips (``bench/grip_slip.py``): it shows the
simulator's floor, not the benchmark.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field

NonNegative = Annotated[float, Field(ge=0.0)]

GRAVITY_MPS2 = 9.81
#: Our gripper's pad friction and grip force limit per pad (the same in both built-ins).
PAD_FRICTION = 1.2
GRIP_FORCE_N = 110.0


class PhysicsProfile(BaseModel):
    """Every simulator setting of a trial. Lengths in metres, forces in newtons."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    name: str = Field(min_length=1, max_length=64)
    # The engine.
    time_step_s: float = Field(gt=0.0, le=0.02, description="Fixed simulation time step.")
    solver_iterations: int = Field(ge=1, le=1000, description="numSolverIterations.")
    contact_breaking_threshold_m: float = Field(gt=0.0, le=0.1)
    friction_anchors: bool = Field(description="frictionAnchor on the bricks.")
    # Contact properties of the bricks and the ground (PyBullet multiplies both bodies').
    brick_lateral_friction: NonNegative
    brick_spinning_friction: NonNegative
    brick_rolling_friction: NonNegative
    ground_lateral_friction: NonNegative
    # Our gripper and arm drive.
    pad_friction: NonNegative = PAD_FRICTION
    pad_spinning_friction: NonNegative = 0.001
    grip_force_n: float = Field(
        GRIP_FORCE_N, gt=0.0, le=500.0, description="Grip force limit per pad."
    )
    finger_speed_mps: float = Field(0.10, gt=0.0, le=1.0)
    arm_force_nm: float = Field(300.0, gt=0.0, le=2000.0)

    def describe(self) -> str:
        """One line for headings: the engine and contact settings that differ by profile."""
        return (
            f"{self.name}: dt 1/{1 / self.time_step_s:.0f} s, {self.solver_iterations} solver "
            f"iterations, contact breaking {self.contact_breaking_threshold_m:g} m, friction "
            f"anchors {'on' if self.friction_anchors else 'off'}, brick friction "
            f"{self.brick_lateral_friction:g}, ground {self.ground_lateral_friction:g}, pads "
            f"{self.pad_friction:g}"
        )


PAPER = PhysicsProfile(
    name="paper",
    time_step_s=1.0 / 240.0,
    solver_iterations=50,
    contact_breaking_threshold_m=0.02,
    friction_anchors=False,
    brick_lateral_friction=0.5,
    brick_spinning_friction=0.0,
    brick_rolling_friction=0.0,
    ground_lateral_friction=1.0,
)

PRECISE = PhysicsProfile(
    name="precise",
    time_step_s=1.0 / 480.0,
    solver_iterations=150,
    contact_breaking_threshold_m=0.002,
    friction_anchors=True,
    brick_lateral_friction=0.8,
    brick_spinning_friction=0.001,
    brick_rolling_friction=0.0,
    ground_lateral_friction=0.8,
)
