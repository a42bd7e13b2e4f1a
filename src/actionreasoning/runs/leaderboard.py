"""The figures a leaderboard row adds to success and Table I: answers accepted at the first
attempt, refusals per brick, and prompt tokens per brick and per brick within the rule.

"Per brick" counts the pattern's bricks in every trial (its targets), failed trials
included; "per brick within the rule" the bricks placed within the success rule's limits.
"""

from __future__ import annotations

from collections.abc import Sequence

from pydantic import BaseModel, ConfigDict, NonNegativeFloat

from actionreasoning.trial.results import FirstAttempts, TrialResult

#: The columns of leaderboard_cells.
LEADERBOARD_COLUMNS = (
    "First answers accepted",
    "Refusals / brick",
    "Prompt tokens / brick",
    "Prompt tokens / brick within the rule",
)


class Leaderboard(BaseModel):
    """A run's leaderboard figures (None where they cannot be had, see each field)."""

    model_config = ConfigDict(frozen=True)

    #: Every agent's answers at attempt 1 of a request (once a brick; the placement agent
    #: twice, and again after a raise), and how many were accepted (or executed) as they
    #: came; None without agents (classical) and for lines written before they were counted.
    first_attempts: FirstAttempts | None
    first_attempts_by_agent: dict[str, FirstAttempts]
    #: Refused and failed answers (repairs included) over the pattern's bricks; None
    #: without a reasoner.
    refusals_per_brick: NonNegativeFloat | None
    #: Prompt tokens over the pattern's bricks and over those placed within the success
    #: rule; None where none were counted (the built-in reasoner spends none) or no brick
    #: was placed within the rule.
    prompt_tokens_per_brick: NonNegativeFloat | None
    prompt_tokens_per_placed_brick: NonNegativeFloat | None


def leaderboard(results: Sequence[TrialResult]) -> Leaderboard:
    """The leaderboard figures of ``results``, summed over them."""
    by_agent: dict[str, FirstAttempts] = {}
    for result in results:
        for agent, counts in result.first_attempts.items():
            by_agent[agent] = by_agent.get(agent, FirstAttempts()) + counts
    total = sum(by_agent.values(), FirstAttempts())
    bricks = sum(len(r.bricks) for r in results)
    placed = sum(r.bricks_placed for r in results)
    tokens = sum(r.llm_usage.prompt_tokens for r in results)
    refusals = sum(n for r in results for row in r.refusals.values() for n in row.values())
    reasoned = bool(bricks) and any(r.llm != "none" for r in results)
    return Leaderboard(
        first_attempts=total if total.asked else None,
        first_attempts_by_agent=by_agent,
        refusals_per_brick=refusals / bricks if reasoned else None,
        prompt_tokens_per_brick=tokens / bricks if tokens and bricks else None,
        prompt_tokens_per_placed_brick=tokens / placed if tokens and placed else None,
    )


def first_attempts_text(counts: FirstAttempts | None) -> str:
    """``58/60 (97 %)``, or a dash where none were counted."""
    if counts is None or not counts.asked:
        return "–"
    return f"{counts.accepted}/{counts.asked} ({100 * counts.accepted / counts.asked:.0f} %)"


def leaderboard_cells(board: Leaderboard | None) -> list[str]:
    """The figures as LEADERBOARD_COLUMNS shows them; dashes for a summary without them."""
    if board is None:
        return ["–"] * len(LEADERBOARD_COLUMNS)
    refusals, tokens = board.refusals_per_brick, board.prompt_tokens_per_brick
    placed = board.prompt_tokens_per_placed_brick
    return [
        first_attempts_text(board.first_attempts),
        "–" if refusals is None else f"{refusals:.2f}",
        "–" if tokens is None else f"{tokens:.0f}",
        "–" if placed is None else f"{placed:.0f}",
    ]


def by_agent_text(board: Leaderboard | None) -> str:
    """Each agent's first answers accepted: ``pre_grasp 10/12, grasp 12/12``; a dash for none."""
    if board is None or not board.first_attempts_by_agent:
        return "–"
    return ", ".join(
        f"{agent} {n.accepted}/{n.asked}" for agent, n in board.first_attempts_by_agent.items()
    )
