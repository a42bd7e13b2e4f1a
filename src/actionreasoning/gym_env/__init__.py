"""The Gymnasium environment ``actionreasoning/BrickStack-v0`` (the ``gym`` extra).

Importing this package registers it::

    import gymnasium
    import actionreasoning.gym_env

    env = gymnasium.make("actionreasoning/BrickStack-v0", pattern="pyramid")

``pattern``, ``physics`` and ``noise`` take a built-in's name or a file; :data:`SCENARIOS`
is every combination of built-ins (``world/scenarios.py``)::

    envs = [gymnasium.make(ENV_ID, **dataclasses.asdict(s)) for s in SCENARIOS]
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "the Gymnasium environment needs Gymnasium: pip install 'actionreasoning[gym]'"
    ) from error

from actionreasoning.gym_env.env import BrickStackEnv
from actionreasoning.world.scenarios import SCENARIOS

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

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "SCENARIOS", "BrickStackEnv"]
