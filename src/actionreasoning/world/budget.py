"""What a trial may spend; the scene enforces it (``sim/scene.py``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated

from pydantic import Field

from actionreasoning.errors import ConfigError


@dataclass(frozen=True)
class TrialBudget:
    """What a trial may spend: simulation steps and wall-clock seconds (positive; a NaN or
    infinite wall time would switch the budget off)."""

    # Bounds for the JSON Schema only: __post_init__ checks them, with its own messages.
    max_steps: Annotated[int, Field(json_schema_extra={"minimum": 1})] = 400_000
    max_wall_s: Annotated[float, Field(json_schema_extra={"exclusiveMinimum": 0})] = 3600.0

    def __post_init__(self) -> None:
        if not (isinstance(self.max_steps, int) and self.max_steps > 0):
            raise ConfigError(f"max_steps {self.max_steps!r}: give a positive whole number")
        if not (math.isfinite(self.max_wall_s) and self.max_wall_s > 0):
            raise ConfigError(
                f"max_trial_s {self.max_wall_s!r}: give a positive, finite number of seconds"
            )
