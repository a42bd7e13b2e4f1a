"""The rules of the benchmark: the methods compared and each trial's seed (success is
``world/success.py``).

Free of the simulator and the reasoners, so reading results (``summary.py``, ``report``)
needs neither.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np


class Method(StrEnum):
    """The reasoning methods a trial can run."""

    AGENTS = "agents"
    SINGLE_AGENT = "single-agent"
    CLASSICAL = "classical"


def trial_seed(run_seed: int, trial: int) -> int:
    """The seed of trial ``trial``: derived from the run seed and the index only."""
    return int(np.random.SeedSequence([run_seed, trial]).generate_state(1)[0])
