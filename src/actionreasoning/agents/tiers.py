"""Reasoning tiers: how much of the SE(3) reasoning the knowledge base does for an agent.

- ``solve``: tools that return the pose to answer with (``grasp_options``,
  ``placement_pose``) besides the checks; a model may copy a tool's result.
- ``check``, the paper's and the default: only tools that check or estimate (collisions,
  contacts, the brick's pose in the hand, reachability and alignment of a pose the model
  proposes, slip); the model composes every waypoint with the knowledge base's formulas.
- ``none``: the state and the formulas only, no tool calls.

Figures of different tiers measure different things: runs record their tier and are
never pooled across tiers.
"""

from __future__ import annotations

from enum import StrEnum
from typing import Final

from actionreasoning.errors import ConfigError


class ToolTier(StrEnum):
    """Which tools the agents get (see the module docstring)."""

    SOLVE = "solve"
    CHECK = "check"
    NONE = "none"


DEFAULT_TIER: Final = ToolTier.CHECK
#: What runs recorded before tiers existed had: today's solve tools.
BEFORE_TIERS: Final = ToolTier.SOLVE

#: The tiers' names, for messages.
TIERS: Final = ", ".join(tier.value for tier in ToolTier)
#: One line per tier, for help texts and prompts.
TIER_HELP: Final[dict[ToolTier, str]] = {
    ToolTier.SOLVE: "grasp_options and placement_pose return the poses to answer with",
    ToolTier.CHECK: "tools only check or estimate; you compose each pose by the formulas",
    ToolTier.NONE: "no tools; you compose each pose from the state by the formulas",
}


def load_tier(name: str) -> ToolTier:
    """The tier named ``name``; an unknown name is refused, naming the tiers."""
    try:
        return ToolTier(name)
    except ValueError:
        raise ConfigError(f"tools {str(name)[:40]!r}: not a tier (tiers: {TIERS})") from None
