"""The bricks placed so far, as a trial goes: what a session reports between two answers.

After every accepted release, the targets released to so far whose brick lies within the
success rule's limits of them (centre offset and rotation error, true poses), judged as the
results line judges its bricks (:func:`~actionreasoning.trial.metrics.placement_of`). A
brick knocked out of its target since counts no more; the count is read at stage ends only,
as snapshots are.
"""

from __future__ import annotations

from actionreasoning.agents.transcript import AgentCall
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.metrics import placement_of
from actionreasoning.trial.runner import TrialObserver
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.stages import Stage, StageEvent
from actionreasoning.world.success import SuccessRule


class PlacedCount(TrialObserver):
    """The number of targets whose brick lies within ``rule`` of them, counted after every
    release (see the module)."""

    def __init__(self, goal: GoalPattern, rule: SuccessRule) -> None:
        self.goal, self.rule = goal, rule
        self.count = 0
        self._placed: dict[int, int] = {}  # target -> brick
        self._last: AgentCall | None = None

    def call(self, scene: Scene, call: AgentCall) -> None:
        self._last = call

    def stage(self, scene: Scene, event: StageEvent) -> None:
        if event.stage != Stage.RELEASE or self._last is None or self._last.target is None:
            return
        self._placed[self._last.target] = event.brick
        self.count = sum(
            self.rule.is_placed(placement_of(*scene.brick_pose(brick), self.goal.targets[target]))
            for target, brick in self._placed.items()
        )
