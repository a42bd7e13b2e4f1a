"""The Gymnasium environment ``actionreasoning/BrickStack-v0`` (the ``gym`` extra).

Importing this package registers it, and one id per built-in scenario
(:data:`SCENARIOS`, ``world/scenarios.py``), ``actionreasoning/BrickStack-<scenario>-v0``,
the same env made with that scenario's ``pattern``, ``physics`` and ``noise``::

    import gymnasium
    import actionreasoning.gym_env

    env = gymnasium.make("actionreasoning/BrickStack-v0", pattern="pyramid")
    env = gymnasium.make("actionreasoning/BrickStack-pyramid-paper-none-v0")  # the same
    envs = [gymnasium.make(scenario_id(s)) for s in SCENARIOS]
"""

from __future__ import annotations

import dataclasses

try:
    import gymnasium
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "the Gymnasium environment needs Gymnasium: pip install 'actionreasoning[gym]'"
    ) from error

from actionreasoning.gym_env.env import BrickStackEnv
from actionreasoning.world.scenarios import SCENARIOS, Scenario

ENV_ID = "actionreasoning/BrickStack-v0"
#: Steps (tool calls and answers) an episode may take before Gymnasium's TimeLimit
#: truncates it: refused answers are free for the trial, so an agent could loop forever.
MAX_EPISODE_STEPS = 2_000


def scenario_id(scenario: Scenario) -> str:
    """The env id of a built-in scenario: ``actionreasoning/BrickStack-pyramid-paper-none-v0``."""
    return f"actionreasoning/BrickStack-{scenario}-v0"


def _register(env_id: str, kwargs: dict[str, str]) -> None:
    if env_id not in gymnasium.registry:
        gymnasium.register(
            id=env_id,
            entry_point="actionreasoning.gym_env.env:BrickStackEnv",
            max_episode_steps=MAX_EPISODE_STEPS,
            kwargs=kwargs,
        )


_register(ENV_ID, {})
for _scenario in SCENARIOS:
    _register(scenario_id(_scenario), dataclasses.asdict(_scenario))

__all__ = ["ENV_ID", "MAX_EPISODE_STEPS", "SCENARIOS", "BrickStackEnv", "scenario_id"]
