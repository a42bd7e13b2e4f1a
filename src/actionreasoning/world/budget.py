"""What a trial may spend; the scene enforces it (``sim/scene.py``)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class TrialBudget:
    """What a trial may spend: simulation steps and wall-clock seconds."""

    max_steps: int = 400_000
    max_wall_s: float = 3600.0
