"""The solver: one sample's trial, run as ``eval`` runs it with Inspect's model answering
the agents; its results line goes to the sample's store (:data:`RESULT`)."""

from __future__ import annotations

import anyio.to_thread
from inspect_ai.model import get_model
from inspect_ai.solver import Generate, Solver, TaskState, solver

from actionreasoning.inspect_task.chat import InspectChat
from actionreasoning.inspect_task.options import TaskOptions
from actionreasoning.inspect_task.schemas import agent_tools
from actionreasoning.reasoners.llm import LLMReasoner
from actionreasoning.trial.provenance import current_provenance, stamp
from actionreasoning.trial.runner import run_trial

#: The store key of the trial's results line (TrialResult as JSON data).
RESULT = "trial_result"


@solver
def gated_trial(
    pattern: str, physics: str, noise: str, tools: str, method: str, seed: int, observe: str
) -> Solver:
    """Run the sample's trial (``metadata["trial"]``) under these options (TaskOptions)."""
    options = TaskOptions(
        pattern=pattern,
        physics=physics,
        noise=noise,
        tools=tools,
        method=method,
        seed=seed,
        observe=observe,
    )
    conditions = options.conditions()
    llm = conditions.config.llm
    assert llm is not None  # eval's default backend settings: their turn limits are used
    by_agent = agent_tools(conditions.config.tools, conditions.config.observe)
    provenance = current_provenance()

    async def solve(state: TaskState, generate: Generate) -> TaskState:
        spec = options.spec(conditions, int(state.metadata["trial"]))
        reasoner = LLMReasoner(InspectChat(get_model(), by_agent), llm.limits)
        run = await anyio.to_thread.run_sync(run_trial, spec, (), reasoner)
        state.store.set(RESULT, stamp(run.result, provenance).model_dump(mode="json"))
        return state

    return solve
