"""The task ``actionreasoning/brick_stack``: the seeded trials of ``actionreasoning eval``,
answered by Inspect's model (docs/inspect.md)."""

from __future__ import annotations

from inspect_ai import Task, task
from inspect_ai.dataset import MemoryDataset, Sample
from inspect_ai.model import GenerateConfig

from actionreasoning.agents.observation import DEFAULT_OBSERVATION
from actionreasoning.agents.tiers import DEFAULT_TIER
from actionreasoning.errors import ActionReasoningError
from actionreasoning.inspect_task.options import TaskOptionError, TaskOptions
from actionreasoning.inspect_task.scoring import trial_outcome
from actionreasoning.inspect_task.solver import gated_trial
from actionreasoning.reasoners.sampling import Sampling
from actionreasoning.trial.rules import Method, trial_seed
from actionreasoning.trial.session import Conditions


@task
def brick_stack(
    pattern: str = "pyramid",
    physics: str = "paper",
    noise: str = "none",
    tools: str = str(DEFAULT_TIER),
    method: str = str(Method.AGENTS),
    trials: int = 10,
    seed: int = 0,
    cache: bool = False,
    observe: str = str(DEFAULT_OBSERVATION),
) -> Task:
    """Trials 0 .. trials-1 of ``actionreasoning eval --seed SEED`` on ``pattern`` under
    ``physics`` and ``noise``, the agents (``method``: the six gated agents or the single
    agent) given the ``tools`` tier and observing ``observe`` (``state``, ``image``: the
    cameras' pictures instead of the bricks' poses, or ``both``); with ``cache``, Inspect
    caches the model's answers (for a week; ``--cache`` sets another expiry).
    Sampling defaults to eval's (greedy, seed 0, 300 tokens); Inspect's options override it."""
    try:
        options = TaskOptions(
            pattern, physics, noise, tools, method, trials, seed, cache, observe=observe
        )
        conditions = options.conditions()
    except ActionReasoningError as error:
        raise TaskOptionError(f"actionreasoning/brick_stack: {error}") from None
    sampling = Sampling()
    return Task(
        dataset=MemoryDataset(samples(options, conditions), name=f"{pattern}-seed-{seed}"),
        solver=gated_trial(pattern, physics, noise, tools, method, seed, observe),
        scorer=trial_outcome(),
        config=GenerateConfig(
            temperature=sampling.temperature,
            seed=sampling.seed,
            max_tokens=sampling.max_tokens,
            cache=True if cache else None,  # None: as Inspect's --cache says
        ),
    )


def samples(options: TaskOptions, conditions: Conditions) -> list[Sample]:
    """One sample per trial, in order: its index, run seed and trial seed in metadata."""
    bricks = len(conditions.goal.targets)
    observe = conditions.config.observe
    seeing = f", observing {observe}" if observe is not DEFAULT_OBSERVATION else ""
    return [
        Sample(
            id=trial,
            input=(
                f"Build {conditions.pattern_name} ({bricks} bricks) with the {options.method} "
                f"method under {options.physics} physics, noise {options.noise}, tools "
                f"{options.tools}{seeing}: trial {trial} of "
                f"`actionreasoning eval --seed {options.seed}` "
                f"(trial seed {trial_seed(options.seed, trial)})."
            ),
            metadata={
                "trial": trial,
                "seed": options.seed,
                "trial_seed": trial_seed(options.seed, trial),
            },
        )
        for trial in range(options.trials)
    ]
