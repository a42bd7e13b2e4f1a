"""Perturbations of a trial, drawn from its seed: perception noise and physical variation.

Perception noise is what the robot's sensors add to every measurement the agents and the
classical script read (brick positions and yaws, pad forces); the metrics always use the
true poses. Physical variation makes each brick of a trial a little different (friction,
mass, size) from the catalogue values the agents are told. Named levels (``--noise
none|low|medium|high``, in ``scenarios.py``) and a file form (JSON/YAML, the fields of
:class:`NoiseLevel`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from actionreasoning.world.models import Sensing
from actionreasoning.world.scene_spec import BrickBody


class _Level(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


class PerceptionNoise(_Level):
    """Gaussian noise on each measurement, drawn anew at every observation."""

    position_std_m: float = Field(0.0, ge=0.0, le=0.05, description="Per axis, brick centres.")
    yaw_std_deg: float = Field(0.0, ge=0.0, le=10.0, description="Brick yaw about world z.")
    force_rel_std: float = Field(0.0, ge=0.0, le=0.5, description="Pad forces, relative.")


class PhysicalVariation(_Level):
    """Uniform per-brick deviations from the catalogue values, drawn once per trial."""

    friction_rel: float = Field(0.0, ge=0.0, le=0.9, description="Lateral friction, +- share.")
    mass_rel: float = Field(0.0, ge=0.0, le=0.9, description="Mass, +- share.")
    size_m: float = Field(0.0, ge=0.0, le=0.01, description="Each edge, +- metres.")


class NoiseLevel(_Level):
    """A named perturbation level."""

    name: str = Field(min_length=1, max_length=64)
    perception: PerceptionNoise = PerceptionNoise()
    variation: PhysicalVariation = PhysicalVariation()

    def sensing(self) -> Sensing:
        """What the robot is told of this level: its sensors' noise and how far a brick's
        mass and friction may be from the catalogue's."""
        return Sensing(
            position_std_m=self.perception.position_std_m,
            yaw_std_deg=self.perception.yaw_std_deg,
            force_rel_std=self.perception.force_rel_std,
            mass_tolerance=self.variation.mass_rel,
            friction_tolerance=self.variation.friction_rel,
        )

    def describe(self) -> str:
        """One line for headings."""
        p, v = self.perception, self.variation
        return (
            f"{self.name}: perception {p.position_std_m * 1000:g} mm, {p.yaw_std_deg:g} deg, "
            f"{p.force_rel_std:.0%} force; bricks +-{v.friction_rel:.0%} friction, "
            f"+-{v.mass_rel:.0%} mass, +-{v.size_m * 1000:g} mm size"
        )


#: Independent streams of a trial's seed: layout uses the seed itself.
VARIATION_STREAM = 1
PERCEPTION_STREAM = 2


def vary_bricks(
    variation: PhysicalVariation, nominals: Sequence[BrickBody], trial_seed: int
) -> list[BrickBody]:
    """One brick per nominal brick, each deviating from it by a draw from the trial's seed
    (the draws are the same whatever the nominal bricks)."""
    rng = np.random.default_rng([trial_seed, VARIATION_STREAM])
    bodies = []
    for nominal in nominals:
        size, mass, friction = rng.uniform(-1.0, 1.0, size=(3,)), *rng.uniform(-1.0, 1.0, size=2)
        bodies.append(
            BrickBody(
                size_m=tuple(
                    float(s + d * variation.size_m)
                    for s, d in zip(nominal.size_m, size, strict=True)
                ),
                mass_kg=nominal.mass_kg * (1.0 + mass * variation.mass_rel),
                lateral_friction=nominal.lateral_friction
                * (1.0 + friction * variation.friction_rel),
            )
        )
    return bodies
