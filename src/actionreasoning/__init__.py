"""actionreasoning: LLM action reasoning in 3D for robot brick stacking."""

__version__ = "0.1.0"
