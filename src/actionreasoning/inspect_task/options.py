"""The task's options (``-T name=value``), checked as ``eval`` checks its own, and the
trials they name: sample ``i`` is trial ``i`` of ``actionreasoning eval --seed SEED``."""

from __future__ import annotations

from dataclasses import dataclass, replace

from inspect_ai._util.error import PrerequisiteError

from actionreasoning.agents.observation import DEFAULT_OBSERVATION, load_observation
from actionreasoning.agents.tiers import DEFAULT_TIER
from actionreasoning.errors import ConfigError
from actionreasoning.trial.rules import Method, check_observation
from actionreasoning.trial.runner import TrialSpec
from actionreasoning.trial.session import Conditions

#: The methods a language model runs (the classical script asks no model).
METHODS = (Method.AGENTS, Method.SINGLE_AGENT)


class TaskOptionError(ConfigError, PrerequisiteError):
    """A refused task option: a ConfigError that ``inspect eval`` prints as its one line
    (Inspect's own errors of this kind are PrerequisiteErrors), without a traceback."""

    def __init__(self, message: str) -> None:
        ConfigError.__init__(self, message)
        self.message = f"error: {message}"


@dataclass(frozen=True)
class TaskOptions:
    """What the trials run under: the pattern, physics profile, noise level, reasoning tier,
    method and what the agents observe by name, how many trials, the run seed, and whether
    Inspect caches the model's answers. A bad value is refused in one line naming the
    option."""

    pattern: str = "pyramid"
    physics: str = "paper"
    noise: str = "none"
    tools: str = str(DEFAULT_TIER)
    method: str = str(Method.AGENTS)
    trials: int = 10
    seed: int = 0
    cache: bool = False
    observe: str = str(DEFAULT_OBSERVATION)

    def __post_init__(self) -> None:
        for name in ("pattern", "physics", "noise", "tools", "method", "observe"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                raise ConfigError(f"-T {name}={value!r}: give a name")
        if self.method not in METHODS:
            raise ConfigError(
                f"-T method={self.method}: give one of {', '.join(METHODS)} "
                "(the classical script asks no model)"
            )
        for name, least in (("trials", 1), ("seed", 0)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < least:
                raise ConfigError(f"-T {name}={value!r}: give a whole number >= {least}")
        if not isinstance(self.cache, bool):
            raise ConfigError(f"-T cache={self.cache!r}: give true or false")
        try:
            check_observation(Method(self.method), load_observation(self.observe))
        except ConfigError as error:
            raise ConfigError(f"-T observe={self.observe}: {error}") from None

    def conditions(self) -> Conditions:
        """The conditions loaded as ``eval`` loads them; a bad name or file is refused."""
        return Conditions.load(
            self.pattern, self.physics, self.noise, tools=self.tools, observe=self.observe
        )

    def spec(self, conditions: Conditions, trial: int) -> TrialSpec:
        """Trial ``trial`` of the run under ``conditions``, with the method asked for."""
        return replace(conditions.spec(self.seed, trial), method=Method(self.method))
