"""``actionreasoning/BrickStack-v0``: one ``eval`` trial of the six gated agents, with the
agents' answers coming from the caller of ``step``.

An episode is one trial (:class:`~actionreasoning.trial.session.TrialSession`). A step is
one action for the agent that waits: a tool call (one of its tools, or one of the gates'
measurements) or an answer, as JSON text (``actions.py``), validated as a language model's
answer is and, if valid, gated and executed by the same controller. The observation is the
measured state the waiting agent is given (``observation.py``); the reward counts bricks
placed (``reward.py``). With ``observe="both"``, each call also carries the cameras'
pictures: the observation adds them under ``pictures`` (a Dict space of arrays); with
``observe="image"`` it has the pictures and no brick's pose.

Seeds: ``reset(seed=s, options={"trial": k})`` is trial k of ``eval --seed s`` under the
same pattern and conditions (k defaults to 0); ``reset()`` goes on with the next trial of
the same run seed, so an env seeded once walks through ``eval --seed s``'s trials in order.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.observation import DEFAULT_OBSERVATION
from actionreasoning.agents.tiers import DEFAULT_TIER
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.errors import ConfigError
from actionreasoning.gym_env.actions import AnswerAction, ToolAction, parse_action
from actionreasoning.gym_env.observation import (
    action_space,
    observation,
    observation_space,
    pictures,
)
from actionreasoning.gym_env.reward import PlacedReward
from actionreasoning.records import FailureCode
from actionreasoning.trial.session import (
    AgentLabel,
    Conditions,
    Refusal,
    RefusalCode,
    SessionError,
    ToolReply,
    TrialSession,
)
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.models import WorldState
from actionreasoning.world.tolerances import Tolerances

#: Trial ends that are budgets outside the task (Gymnasium's truncation), not its outcome.
TRUNCATIONS = frozenset({FailureCode.STEP_BUDGET, FailureCode.TIME_BUDGET})
#: ``info``'s keys and the type of each, the same at every reset and step, so that
#: Gymnasium's vector envs can merge them: they merge a dict key by key (``refusal`` always
#: has ``code`` and ``detail``) and keep other values whole, per env. The records with
#: optional parts (the agent call, the trial's result) are JSON text, "" when there is none.
INFO_TYPES: dict[str, type] = {
    "agent": str,  # the waiting agent; "" once none waits
    "prompt": str,  # its prompt; ""
    "tools": list,  # its tools' names; []
    "refusal": dict,  # {"code", "detail"}: why the step changed nothing; both "" if it did
    "tool_results": list,  # the step's tool replies: {"tool", "result", "refusal"} each
    "call": str,  # the judged answer's record (gates, outcome, feedback): its transcript line
    "result": str,  # the ended trial's results.jsonl line; "" while it runs
    "seed": int,  # the run seed
    "trial": int,  # the trial of that run seed
}


class BrickStackEnv(gymnasium.Env[dict[str, Any], str]):
    """Brick stacking with the six gated agents, answered by the caller: see the module."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}  # noqa: RUF012

    def __init__(
        self,
        pattern: str = "pyramid",
        physics: str = "paper",
        noise: str = "none",
        render_mode: str | None = None,
        max_trial_s: float = TrialBudget().max_wall_s,
        tools: str = DEFAULT_TIER.value,
        answer_errors: float = 0.0,
        observe: str = DEFAULT_OBSERVATION.value,
    ) -> None:
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ConfigError(f"render_mode {render_mode!r}: use 'rgb_array' or None")
        self.render_mode = render_mode
        if isinstance(max_trial_s, bool) or not isinstance(max_trial_s, int | float):
            raise ConfigError(
                f"max_trial_s {max_trial_s!r}: give a positive, finite number of seconds, not "
                f"a {type(max_trial_s).__name__}"
            )
        self.conditions = Conditions.load(
            pattern,
            physics,
            noise,
            TrialBudget(max_wall_s=max_trial_s),
            tools,
            answer_errors=_answer_errors(answer_errors),
            observe=observe,
        )
        Tolerances.derive().for_goal(self.conditions.goal)  # joints the gates work with
        self.observe = self.conditions.config.observe
        self.with_pictures = self.observe.pictures
        self.observation_space = observation_space(len(self.conditions.goal.targets), self.observe)
        self.action_space = action_space()
        self.session: TrialSession | None = None
        self._run_seed: int | None = None
        self._trial = -1
        self._state: WorldState | None = None
        #: The pictures the last question carried, shown on once the trial has ended.
        self._pictures: dict[str, np.ndarray] = {}
        self._reward = PlacedReward()

    # --- Gymnasium's API ----------------------------------------------------------------
    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Start trial ``options["trial"]`` (default: 0 after a seed, else the next) of run
        seed ``seed`` (default: the last one; the first is drawn from the env's generator)."""
        super().reset(seed=seed)
        options = dict(options or {})
        trial = options.pop("trial", None)
        if options:
            raise ConfigError(f"unknown reset options {sorted(options)}: the one option is trial")
        run_seed = seed if seed is not None else self._run_seed
        if run_seed is None:
            run_seed = int(self.np_random.integers(2**31))
        if trial is None:
            trial = 0 if seed is not None else self._trial + 1
        spec = self.conditions.spec(run_seed, trial)  # refused: the env stays as it was
        self._run_seed = run_seed
        self._close_session()
        self._trial = trial
        self._reward = PlacedReward()
        self.session = TrialSession(
            spec, agent=AgentLabel.GYM, final_picture=self.render_mode == "rgb_array"
        )
        request, result = self.session.request, self.session.result
        if request is None:
            # Ended (out of budget, say) before its first question: no trial to step.
            self._close_session()
            self.session, self._state = None, None
            failure = None if result is None else result.failure
            why = "" if failure is None else f": {failure.reason} ({failure.detail})"
            raise SessionError(f"trial {trial} ended before an agent asked{why}")
        self._state = request.state
        self._pictures = pictures(request.pictures) if self.with_pictures else {}
        return self._observation(), self._info()

    def step(self, action: str) -> tuple[dict[str, Any], float, bool, bool, dict[str, Any]]:
        """Run one tool call or answer for the waiting agent (see the module)."""
        session = self._session()
        info: dict[str, Any] = {}
        parsed = parse_action(action)
        if isinstance(parsed, Refusal):
            info["refusal"] = parsed
        elif session.done:
            info["refusal"] = Refusal(code=RefusalCode.TRIAL_OVER, detail="call reset()")
        elif isinstance(parsed, ToolAction):
            tool = session.use_tool(parsed.name, parsed.arguments)
            info |= {"refusal": tool.refusal, "tool_results": [tool]}
        else:
            assert isinstance(parsed, AnswerAction)
            reply = session.answer(parsed.text)
            info |= {"refusal": reply.refusal, "tool_results": reply.tools, "call": reply.call}
        request = session.request
        if request is not None:
            self._state = request.state
            self._pictures = pictures(request.pictures) if self.with_pictures else {}
        reward = self._reward.step(session)
        terminated, truncated = self._ends()
        return self._observation(), reward, terminated, truncated, self._info(**info)

    def render(self) -> np.ndarray | None:
        """The overview camera's picture (height x width x 3, uint8) of the scene now, or of
        the final scene once the trial has ended."""
        if self.render_mode is None:
            return None
        return self._session().picture()

    def close(self) -> None:
        """End the trial in progress (``abandoned``), if any."""
        self._close_session()
        super().close()

    # --- helpers ------------------------------------------------------------------------
    def _session(self) -> TrialSession:
        if self.session is None:
            raise gymnasium.error.ResetNeeded("call reset() before step() or render()")
        return self.session

    def _close_session(self) -> None:
        if self.session is not None:
            self.session.close()

    def _observation(self) -> dict[str, Any]:
        assert self._state is not None and self.session is not None
        request = self.session.request
        agent = None if request is None else str(request.spec.key)
        shown = observation(self._state, agent, self.observe)
        return shown | ({"pictures": self._pictures} if self.with_pictures else {})

    def _ends(self) -> tuple[bool, bool]:
        """(terminated, truncated) in Gymnasium's sense."""
        assert self.session is not None
        result = self.session.result
        if result is None:
            return False, False
        truncated = result.failure is not None and result.failure.reason in TRUNCATIONS
        return not truncated, truncated

    def _info(
        self,
        refusal: Refusal | None = None,
        tool_results: list[ToolReply] | None = None,
        call: AgentCall | None = None,
    ) -> dict[str, Any]:
        """What the step did and the question that waits now: the same keys, each of one
        type, at every reset and step (see :data:`INFO_TYPES`)."""
        assert self.session is not None
        request, result = self.session.request, self.session.result
        return {
            "agent": "" if request is None else str(request.spec.key),
            "prompt": "" if request is None else request.prompt,
            "tools": [] if request is None else list(request.spec.tools),
            "refusal": (
                {"code": "", "detail": ""} if refusal is None else refusal.model_dump(mode="json")
            ),
            "tool_results": [reply.model_dump(mode="json") for reply in tool_results or ()],
            "call": "" if call is None else call.model_dump_json(),
            "result": "" if result is None else result.model_dump_json(),
            "seed": self._run_seed,
            "trial": self._trial,
        }


def _answer_errors(rate: object) -> AnswerErrors:
    """``eval --answer-errors RATE``: the caller's answers corrupted with probability
    ``rate`` (0 to 1), as any reasoner's are; refused in one line otherwise."""
    if (
        isinstance(rate, bool)
        or not isinstance(rate, int | float)
        or not 0.0 <= rate <= 1.0  # NaN too
    ):
        raise ConfigError(f"answer_errors {rate!r}: give a rate from 0 to 1")
    return AnswerErrors(rate=rate + 0.0)  # -0 is 0
