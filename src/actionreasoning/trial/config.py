"""Everything a trial runs under, in one frozen record: what run.json holds and hashes.

A :class:`TrialConfig` is made once per run and handed to every trial; each of its parts
goes to the one place that uses it (the scene, the controller, the agents, the scoring),
so the configuration recorded is the one run. A trial adds only its method, pattern, seed
and index (:class:`~actionreasoning.trial.runner.TrialSpec`).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, field_serializer, model_validator

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.orchestrator import Budgets
from actionreasoning.agents.tiers import DEFAULT_TIER, ToolTier
from actionreasoning.agents.verification import Verification
from actionreasoning.control.limits import ControllerLimits
from actionreasoning.control.safety import SafetyLimits
from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.reasoners.llm import LLMLimits
from actionreasoning.reasoners.sampling import RecordedSampling, Sampling
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.noise import NoiseLevel
from actionreasoning.world.physics import PAPER, PhysicsProfile
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import Tolerances

#: Simulated seconds the bricks settle after they spawn, and after the method has ended.
SPAWN_SETTLE_S = 0.25
FINAL_SETTLE_S = 1.0


class Backend(BaseModel):
    """What run.json records of a reasoning backend: which one, its turn budgets, whether
    the built-in reasoner answers once they are spent, its sampling settings and the names
    of the extra headers it is sent (never their values).

    Sampling settings at their defaults and an empty ``headers`` are left out, so a run at
    the defaults records (and hashes) what runs recorded before these settings existed."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    spec: str
    limits: LLMLimits
    fallback: bool
    sampling: RecordedSampling = Sampling()
    headers: Annotated[tuple[str, ...], Field(exclude_if=lambda names: not names)] = ()


class TrialConfig(BaseModel):
    """The scene, physics, perturbations, gate tolerances, budgets, controller and safety
    limits, success rule, reasoning backend, answer errors, reasoning tier (``tools``:
    which tools the agents get, :mod:`~actionreasoning.agents.tiers`), rung of
    verification (``verify``) and what the agents observe (``observe``: the state's poses,
    the cameras' pictures or both, :mod:`~actionreasoning.agents.observation`) of every
    trial of a run.

    ``llm`` is None for the classical script, which asks no reasoner. Of a backend only
    what defines it is recorded (:class:`Backend`): where its server is and how patiently
    it is asked, a --record file, and the structured-output mode
    :func:`~actionreasoning.reasoners.factory.prepare` negotiates are how a run reaches it,
    and may change on resume. run.json records the configuration as prepared: with the
    names of a server's extra headers, and a replay's sampling settings (the recording's).
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    scene: SceneSpec = SceneSpec()
    physics: PhysicsProfile = PAPER
    noise: NoiseLevel = NOISE["none"]
    tolerances: Tolerances = Tolerances()
    retries: Budgets = Budgets()
    budget: TrialBudget = TrialBudget()
    controller: ControllerLimits = ControllerLimits()
    safety: SafetyLimits = SafetyLimits()
    success_rule: SuccessRule = SuccessRule()
    llm: LLMConfig | None = LLMConfig()
    answer_errors: AnswerErrors = AnswerErrors()
    tools: ToolTier = DEFAULT_TIER
    #: The rung of verification (agents/verification.py): which verdicts refuse an answer;
    #: None: the method's own (``rung_of``). Left out of run.json when None, so runs from
    #: before rungs existed resume.
    verify: Annotated[Verification | None, Field(exclude_if=lambda rung: rung is None)] = None
    #: Left out of run.json when ``state``, so runs from before pictures existed resume.
    observe: Annotated[Observation, Field(exclude_if=lambda shown: shown is Observation.STATE)] = (
        DEFAULT_OBSERVATION
    )

    @model_validator(mode="after")
    def _budget_covers_a_trial(self) -> TrialConfig:
        """Refuse a step budget that cannot simulate the least any trial takes: the two
        settles and one brick's grasp and release (the gripper closing and opening)."""
        time_step, steps = self.physics.time_step_s, self.budget.max_steps
        least_s = SPAWN_SETTLE_S + 2 * self.controller.gripper_s + FINAL_SETTLE_S
        if steps * time_step < least_s:
            raise ConfigError(
                f"physics {self.physics.name!r}: {steps} steps (--max-steps) of "
                f"{time_step:g} s (time_step_s) simulate {steps * time_step:.3g} s, and a "
                f"trial takes at least {least_s:g} s (the settles and one brick's grasp and "
                "release): raise the time step or the step budget"
            )
        return self

    @model_validator(mode="after")
    def _pictures_need_a_tier_without_poses(self) -> TrialConfig:
        """Refuse the image tier with the solve tools: they read the bricks' poses."""
        if not self.observe.poses and self.tools is ToolTier.SOLVE:
            raise ConfigError(
                f"--observe {self.observe} shows no brick's pose, and the solve tier's tools "
                "read them: use --tools check or none"
            )
        return self

    @field_serializer("llm")
    def _backend(self, llm: LLMConfig | None) -> Backend | None:
        if llm is None:
            return None
        return Backend(
            spec=llm.spec,
            limits=llm.limits,
            fallback=llm.fallback,
            sampling=llm.sampling,
            headers=llm.headers,
        )
