"""The prompt an agent is really sent, and the pictures with it: trial 0 run with the
built-in reasoner until the agent is first asked."""

from __future__ import annotations

from dataclasses import dataclass

from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.reasoner import AgentReply, AgentRequest
from actionreasoning.agents.spec import SINGLE_AGENT, AgentKey
from actionreasoning.agents.verification import Verification
from actionreasoning.errors import ActionReasoningError
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.trial.runner import TrialSpec, trial_world
from actionreasoning.trial.sim_world import SimWorld
from actionreasoning.world.pictures import Picture


class _Caught(Exception):
    """Raised with the request once the agent asked for is asked."""

    def __init__(self, request: AgentRequest) -> None:
        super().__init__("prompt caught")
        self.request = request


@dataclass
class _Catcher:
    """The built-in reasoner, stopping the build at the first request of ``agent``."""

    agent: AgentKey
    name: str = "builtin"

    def decide(self, request: AgentRequest) -> AgentReply:
        if request.spec.key == self.agent:
            raise _Caught(request)
        return BuiltinReasoner().decide(request)


def first_prompt(spec: TrialSpec, agent: AgentKey) -> tuple[str, tuple[Picture, ...]]:
    """The prompt ``agent`` gets first in ``spec``'s trial, and the pictures it carries
    (none unless the agents observe pictures)."""
    with trial_world(spec) as world:
        sim = SimWorld(world.controller, spec.goal, world.sensor)
        catcher, config = _Catcher(agent), spec.config
        runner = Orchestrator(
            sim,
            catcher,
            config.tolerances,
            config.retries,
            tier=config.tools,
            verify=Verification.NONE
            if agent == SINGLE_AGENT
            else config.verify or Verification.FULL,
            single_agent=agent == SINGLE_AGENT,
            observation=config.observe,
        )
        try:
            result = runner.build(spec.goal)
        except _Caught as caught:
            return caught.request.prompt, caught.request.pictures
    failure = result.failure
    why = f"the build stopped first ({failure.reason}: {failure.detail})" if failure else "done"
    raise ActionReasoningError(f"agent {agent} is never asked in trial 0: {why}")
