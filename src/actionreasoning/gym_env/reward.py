"""The reward: one point per brick placed within the success rule, as the trial goes.

The potential of a moment is the session's count of bricks placed
(:attr:`~actionreasoning.trial.session.TrialSession.placed`): the targets whose brick lies
within the success rule's limits of it (centre offset and rotation error, true poses),
counted after every accepted release and, at the end, the trial's ``bricks_placed`` (after
the final settle). A step's reward is the change of the potential: +1 for a brick released
within the rule, -1 for one knocked out of it since, 0 for everything else (a tool call, a
refusal, an answer that moved the arm). An episode's rewards add up to the trial's
``bricks_placed``.
"""

from __future__ import annotations

from actionreasoning.trial.session import TrialSession


class PlacedReward:
    """The rewards of one episode: each the change of the potential since the last."""

    def __init__(self) -> None:
        self.potential = 0

    def step(self, session: TrialSession) -> float:
        """The reward of the step just taken in ``session``."""
        placed = session.placed
        reward, self.potential = placed - self.potential, placed
        return float(reward)
