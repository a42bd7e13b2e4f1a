"""Wilson intervals, McNemar's exact test and the bootstrap interval, against figures
computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import binomtest

from actionreasoning.runs.statistics import bootstrap_mean, mcnemar_exact, wilson

# (successes, trials, low, high): p ± z sqrt(p(1 - p)/n + z²/4n²), centred on
# (p + z²/2n), both over 1 + z²/n, with z = 1.959964.
WILSON = [
    (17, 20, 0.639581, 0.947631),
    (19, 20, 0.763869, 0.991119),
    (0, 10, 0.0, 0.277533),  # z²/n / (1 + z²/n)
    (10, 10, 0.722467, 1.0),  # 1 - the above
    (1, 1, 0.206549, 1.0),
]


@pytest.mark.parametrize(("k", "n", "low", "high"), WILSON)
def test_wilson_intervals_are_the_hand_computed_ones(
    k: int, n: int, low: float, high: float
) -> None:
    interval = wilson(k, n)
    assert interval is not None
    assert (interval.low, interval.high) == pytest.approx((low, high), abs=1e-6)
    assert interval.low <= k / n <= interval.high


def test_no_trials_give_no_interval_and_impossible_counts_are_refused() -> None:
    assert wilson(0, 0) is None
    with pytest.raises(ValueError, match="11 successes of 10 trials"):
        wilson(11, 10)


# (b, c, p): p = min(1, 2 sum_{i <= min(b, c)} C(b + c, i) / 2^(b + c))
MCNEMAR = [
    (0, 5, 2 / 32),  # 0.0625: five discordant trials all one way are not enough
    (5, 0, 2 / 32),
    (0, 6, 2 / 64),  # 0.03125
    (1, 8, 2 * (1 + 9) / 512),  # 0.0390625
    (2, 7, 2 * (1 + 9 + 36) / 512),  # 0.1796875
    (3, 3, 1.0),  # 2 * 42/64 > 1
    (0, 0, 1.0),  # no discordant trial: no evidence either way
]


@pytest.mark.parametrize(("b", "c", "p"), MCNEMAR)
def test_mcnemar_p_values_are_the_hand_computed_ones(b: int, c: int, p: float) -> None:
    test = mcnemar_exact(b, c)
    assert (test.b, test.c) == (b, c)
    assert test.p == pytest.approx(p, rel=1e-12)
    if b + c:
        assert test.p == pytest.approx(binomtest(min(b, c), b + c, 0.5).pvalue, rel=1e-12)


def test_mcnemar_refuses_negative_counts() -> None:
    with pytest.raises(ValueError, match="b=-1"):
        mcnemar_exact(-1, 3)


def test_the_bootstrap_interval_is_deterministic_and_covers_the_mean() -> None:
    values = [0.16, 0.21, 0.18, 0.15, 0.30, 0.17, 0.19, 0.22, 0.14, 0.20]
    first, second = bootstrap_mean(values), bootstrap_mean(list(values))
    assert first is not None and first == second
    assert first.low < float(np.mean(values)) < first.high
    assert min(values) < first.low and first.high < max(values)
    # Mean 0.192, standard error 0.0138: the percentile interval is about ± 1.96 of them.
    assert first.high - first.low == pytest.approx(2 * 1.96 * np.std(values) / math.sqrt(10), 0.2)


def test_one_value_gives_a_degenerate_interval_and_none_gives_none() -> None:
    interval = bootstrap_mean([2.5])
    assert interval is not None and (interval.low, interval.high) == (2.5, 2.5)
    assert bootstrap_mean([]) is None
