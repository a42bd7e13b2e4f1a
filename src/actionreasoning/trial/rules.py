"""The rules of the benchmark: the methods compared and each trial's seed (success is
``world/success.py``).

Free of the simulator and the reasoners, so reading results (``summary.py``, ``report``)
needs neither.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np

from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.verification import Verification
from actionreasoning.errors import ConfigError


class Method(StrEnum):
    """The reasoning methods a trial can run."""

    AGENTS = "agents"
    SINGLE_AGENT = "single-agent"
    CLASSICAL = "classical"


def trial_seed(run_seed: int, trial: int) -> int:
    """The seed of trial ``trial``: derived from the run seed and the index only."""
    return int(np.random.SeedSequence([run_seed, trial]).generate_state(1)[0])


def check_rung(method: Method, verify: Verification | None) -> None:
    """Refuse a rung of verification the method cannot run under, in one line."""
    if method is Method.SINGLE_AGENT and verify not in (None, Verification.NONE):
        raise ConfigError(f"--method single-agent has no stage gating: drop --verify {verify}")
    if method is Method.CLASSICAL and verify is not None:
        raise ConfigError(f"--method classical verifies nothing; drop --verify {verify}")


def check_observation(method: Method, observe: Observation) -> None:
    """Refuse an observation the method cannot run under, in one line."""
    if method is Method.CLASSICAL and observe is not DEFAULT_OBSERVATION:
        raise ConfigError(f"--method classical asks no agent; drop --observe {observe}")
    if method is Method.SINGLE_AGENT and not observe.poses:
        raise ConfigError(
            f"--method single-agent names its brick by id: observe state or both, not {observe}"
        )


def rung_of(method: Method, verify: Verification | None) -> Verification | None:
    """The rung of verification a method runs under: ``verify`` if given, else the method's
    own (the six agents' full verification, the single agent's none); None for the
    classical script, which verifies nothing."""
    if method is Method.CLASSICAL:
        return None
    if verify is not None:
        return verify
    return Verification.NONE if method is Method.SINGLE_AGENT else Verification.FULL
