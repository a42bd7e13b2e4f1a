"""The reward: one point per brick placed within the success rule, as the trial goes.

The potential of a moment is the number of targets whose brick lies within the success
rule's limits of it (centre offset and rotation error, true poses), counted after every
accepted release and, at the end, the trial's ``bricks_placed`` (after the final settle).
A step's reward is the change of the potential: +1 for a brick released within the rule,
-1 for one knocked out of it since, 0 for everything else (a tool call, a refusal, an
answer that moved the arm). An episode's rewards add up to the trial's ``bricks_placed``.
"""

from __future__ import annotations

from actionreasoning.agents.transcript import AgentCall
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.metrics import brick_metrics
from actionreasoning.trial.runner import TrialObserver
from actionreasoning.world.boxes import Box
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.stages import Stage, StageEvent
from actionreasoning.world.success import SuccessRule


class PlacedCount(TrialObserver):
    """The potential during a trial: after every release, the targets whose brick lies
    within ``rule`` of them. Reads brick poses at stage ends only, as snapshots do."""

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
        self.count = 0
        for target, brick in self._placed.items():
            goal = self.goal.targets[target]
            position, quat = scene.brick_pose(brick)
            metrics = brick_metrics(
                Box(position, quat, goal.size_m),
                Box(goal.pose.position_m, goal.pose.quat_xyzw, goal.size_m),
            )
            self.count += self.rule.is_placed(metrics)
