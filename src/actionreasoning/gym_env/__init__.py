"""The Gymnasium environment ``actionreasoning/BrickStack-v0`` (the ``gym`` extra).

Importing this package registers it::

    import gymnasium
    import actionreasoning.gym_env

    env = gymnasium.make("actionreasoning/BrickStack-v0", pattern="pyramid")
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "the Gymnasium environment needs Gymnasium: pip install 'actionreasoning[gym]'"
    ) from error

from actionreasoning.gym_env.env import BrickStackEnv

ENV_ID = "actionreasoning/BrickStack-v0"
#: Steps (tool calls and answers) an episode may take before Gymnasium's TimeLimit
#: truncates it: refused answers are free for the trial, so an agent could loop forever.
MAX_EPISODE_STEPS = 2_000

if ENV_ID not in gymnasium.registry:
    gymnasium.register(
        id=ENV_ID,
        entry_point="actionreasoning.gym_env.env:BrickStackEnv",
        max_episode_steps=MAX_EPISODE_STEPS,
    )

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "BrickStackEnv"]
