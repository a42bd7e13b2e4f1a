"""The statistics that go with every compared number: a Wilson interval on a success rate,
McNemar's exact test on two methods run on the same trials, a bootstrap interval on a mean.

All 95 %, all pure functions of their inputs (the bootstrap's generator is seeded here).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from statistics import NormalDist

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

#: The two-sided 95 % quantile of the standard normal, 1.95996...
Z_95 = NormalDist().inv_cdf(0.975)
#: The bootstrap's resamples and its generator's seed: the same values give the same interval.
BOOTSTRAP_RESAMPLES = 10_000
BOOTSTRAP_SEED = 0
#: Resamples drawn at once, so that memory stays small for many trials.
_CHUNK = 1_000


class Interval(BaseModel):
    """A 95 % interval, in the units of what it bounds."""

    model_config = ConfigDict(frozen=True)

    low: float
    high: float


class RateInterval(Interval):
    """A 95 % interval of a rate: fractions in [0, 1]."""

    low: float = Field(ge=0.0, le=1.0)
    high: float = Field(ge=0.0, le=1.0)


class McNemar(BaseModel):
    """McNemar's exact test on paired trials: ``b`` trials only the first method succeeded
    in, ``c`` only the second; ``p`` the two-sided exact p-value."""

    model_config = ConfigDict(frozen=True)

    b: int
    c: int
    p: float


def wilson(successes: int, trials: int) -> RateInterval | None:
    """The Wilson score 95 % interval of a success rate (fractions in [0, 1]); None for no
    trials."""
    if not 0 <= successes <= trials:
        raise ValueError(f"{successes} successes of {trials} trials")
    if trials == 0:
        return None
    rate, z2 = successes / trials, Z_95**2
    scale = 1 + z2 / trials
    centre = (rate + z2 / (2 * trials)) / scale
    half = Z_95 * math.sqrt(rate * (1 - rate) / trials + z2 / (4 * trials**2)) / scale
    # At 0/n and n/n a bound is 0 or 1 exactly, which rounding would miss by a hair.
    return RateInterval(
        low=0.0 if successes == 0 else centre - half,
        high=1.0 if successes == trials else centre + half,
    )


def mcnemar_exact(b: int, c: int) -> McNemar:
    """McNemar's exact test: under the null, each of the b + c discordant trials is won by
    either method with probability 1/2, so p = min(1, 2 P[X <= min(b, c)]) with
    X ~ Bin(b + c, 1/2); p = 1 without discordant trials."""
    if b < 0 or c < 0:
        raise ValueError(f"discordant counts must not be negative: b={b}, c={c}")
    n = b + c
    tail = sum(math.comb(n, i) for i in range(min(b, c) + 1))
    return McNemar(b=b, c=c, p=min(1.0, 2 * tail / 2**n))


def bootstrap_mean(values: Sequence[float]) -> Interval | None:
    """The 95 % percentile bootstrap interval of the mean of ``values``: the 2.5th and 97.5th
    percentiles of the means of BOOTSTRAP_RESAMPLES resamples with replacement, drawn by a
    generator seeded with BOOTSTRAP_SEED. One value gives the interval [value, value]; none
    gives None."""
    data = np.asarray(values, dtype=float)
    if data.size == 0:
        return None
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    means = np.concatenate(
        [
            data[rng.integers(0, data.size, size=(min(_CHUNK, left), data.size))].mean(axis=1)
            for left in range(BOOTSTRAP_RESAMPLES, 0, -_CHUNK)
        ]
    )
    low, high = np.percentile(means, [2.5, 97.5])
    return Interval(low=float(low), high=float(high))
