"""Paired comparisons: two rows of a report run on the same trials, compared with McNemar's
exact test.

Two rows are paired on a pattern when they ran the same pattern content under the same
physics, noise, answer errors, success rule and scene (every run.json value under those
names), and in the same reasoning tier where both have a reasoner (the classical script
has none, so any tier pairs with it); the method, the backend and its settings, the rung
of verification and the budgets may differ. Their trials are paired by ``trial_seed``, the
seed each trial's initial scene comes from; only trials both rows ran are compared.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from itertools import combinations

from actionreasoning.report.collect import Group, labels, patterns
from actionreasoning.runs.markdown import captioned_table
from actionreasoning.runs.statistics import McNemar, mcnemar_exact

#: run.json values two rows must share to be paired (a name and every name under it).
PAIRED_ON = ("physics", "noise", "answer_errors", "success_rule", "scene")
#: The pattern column of a comparison pooled over every pattern both rows ran.
ALL_PATTERNS = "all"


@dataclass(frozen=True)
class Pair:
    """Two rows on one pattern (or ALL_PATTERNS): over the trials both ran, how often each
    succeeded, and McNemar's test (b: only the first succeeded, c: only the second)."""

    first: str
    second: str
    pattern: str
    common: int  # trials both rows ran (same trial_seed)
    first_successes: int
    second_successes: int
    test: McNemar

    @property
    def cells(self) -> list[str]:
        """The row as PAIR_COLUMNS shows it."""
        return [
            self.first,
            self.second,
            self.pattern,
            str(self.common),
            str(self.first_successes),
            str(self.second_successes),
            str(self.test.b),
            str(self.test.c),
            f"{self.test.p:.3g}",
        ]


PAIR_COLUMNS = (
    "First",
    "Second",
    "Pattern",
    "Paired trials",
    "First succeeded",
    "Second succeeded",
    "b (first only)",
    "c (second only)",
    "p (McNemar, exact)",
)

PAIRS_CAPTION = (
    "Two rows on the same pattern under the same physics, noise, answer errors, success rule "
    "and scene, and the same tools tier where both have a reasoner, over the trials both ran "
    "from the same trial seed (paired trials); b: those only the first succeeded in, c: only "
    "the second; p: McNemar's exact two-sided test on the b + c discordant trials. "
    f"{ALL_PATTERNS}: over every pattern both ran."
)


def _pairable(a: Group, b: Group) -> bool:
    """Whether ``a`` and ``b`` (of one pattern) ran under the same PAIRED_ON values and,
    where both have a reasoner, in the same tier."""
    tiers = {g.results[0].tools for g in (a, b) if g.results[0].llm != "none"}
    return len(tiers) <= 1 and _shared(a) == _shared(b)


def _shared(group: Group) -> dict[str, object]:
    """The group's run.json values under PAIRED_ON."""
    return {
        name: value
        for name, value in group.conditions.items()
        if name.split(".", 1)[0] in PAIRED_ON
    }


def paired_comparisons(groups: Sequence[Group]) -> list[Pair]:
    """Every two rows paired on a pattern, in the order of rows and patterns, each two
    paired on more than one pattern also pooled over them (ALL_PATTERNS); rows without a
    trial in common are left out."""
    by_key = {(g.label, g.pattern): g for g in groups}
    pairs: list[Pair] = []
    for first, second in combinations(labels(groups), 2):
        found = []
        for pattern in patterns(groups):
            a, b = by_key.get((first, pattern)), by_key.get((second, pattern))
            pair = None if a is None or b is None or not _pairable(a, b) else _compare(a, b)
            if pair is not None:
                found.append(pair)
        pairs += found
        if len(found) > 1:
            pairs.append(
                Pair(
                    first=first,
                    second=second,
                    pattern=ALL_PATTERNS,
                    common=sum(p.common for p in found),
                    first_successes=sum(p.first_successes for p in found),
                    second_successes=sum(p.second_successes for p in found),
                    test=mcnemar_exact(sum(p.test.b for p in found), sum(p.test.c for p in found)),
                )
            )
    return pairs


def _compare(a: Group, b: Group) -> Pair | None:
    """``a`` against ``b`` over the trials both ran; None if they ran none in common."""
    first = {r.trial_seed: r.success for r in a.results}
    second = {r.trial_seed: r.success for r in b.results}
    common = [seed for seed in first if seed in second]
    if not common:
        return None
    return Pair(
        first=a.label,
        second=b.label,
        pattern=a.pattern,
        common=len(common),
        first_successes=sum(first[s] for s in common),
        second_successes=sum(second[s] for s in common),
        test=mcnemar_exact(
            sum(first[s] and not second[s] for s in common),
            sum(second[s] and not first[s] for s in common),
        ),
    )


def pair_lines(pairs: Sequence[Pair]) -> list[str]:
    """The paired comparisons as markdown: what they are, then a table (PAIR_COLUMNS)."""
    rows = [pair.cells for pair in pairs]
    return captioned_table(f"Paired comparisons. {PAIRS_CAPTION}", PAIR_COLUMNS, rows)
