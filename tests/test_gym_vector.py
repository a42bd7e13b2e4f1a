"""actionreasoning/BrickStack-v0 in Gymnasium's vector envs (``gymnasium.make_vec``, sync and
async): every info merges, whatever each env's step did; agents that read nothing but the
vector env's observations and infos build to the end of their episodes; and ``close()``
returns, after an error in a worker too."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from test_gym_env import assert_typed

from actionreasoning.gym_env import ENV_ID
from actionreasoning.gym_env.env import INFO_TYPES
from actionreasoning.reasoners import reference_model
from actionreasoning.reasoners.llm import TOOL_RESULTS

MODES = ["sync", "async"]
#: One brick on the table: a whole trial in a few seconds.
ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}
REACHABILITY = json.dumps(
    {"tool": "reachability", "arguments": {"pose": {"position_m": [0.5, 0.0, 0.3]}}}
)


@pytest.fixture
def one_brick(tmp_path: Path) -> Path:
    path = tmp_path / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


@pytest.fixture(params=MODES)
def envs(request: pytest.FixtureRequest) -> Iterator[gymnasium.vector.VectorEnv]:
    made = gymnasium.make_vec(ENV_ID, num_envs=2, vectorization_mode=request.param)
    yield made
    made.close()


def env_info(infos: dict[str, Any], index: int) -> dict[str, Any]:
    """Env ``index``'s info out of the vector env's merged ``infos``, as the env gave it."""
    info = {key: infos[key][index] for key in INFO_TYPES if key != "refusal"}
    info["refusal"] = {key: infos["refusal"][key][index] for key in ("code", "detail")}
    return {**info, "seed": int(info["seed"]), "trial": int(info["trial"])}


def assert_merged(infos: dict[str, Any], envs: int = 2) -> None:
    """Every env's info had every key, each of its type: the merge is each env's info."""
    assert set(infos) == {*INFO_TYPES, *(f"_{key}" for key in INFO_TYPES)}
    assert all(infos[f"_{key}"].all() for key in INFO_TYPES)
    assert set(infos["refusal"]) == {"code", "_code", "detail", "_detail"}
    assert infos["seed"].dtype == infos["trial"].dtype == np.int_
    for index in range(envs):
        assert_typed(env_info(infos, index))


@pytest.mark.timeout(120)
def test_infos_merge_whatever_each_env_did(envs: gymnasium.vector.VectorEnv) -> None:
    """A tool call in one env beside a judged answer or a refused action in the other, and
    the other way round: it failed on the second step (``refusal`` and ``call`` were None in
    one env and a dict in the other), and the async env then hung in close()."""
    observed, infos = envs.reset(seed=0)
    assert_merged(infos)
    # Brick 0 approached through the middle of brick 1: judged, refused by a gate, no move.
    judged = [
        json.dumps({"answer": {"brick_id": 0, "target_index": 0, "waypoint": waypoint}})
        for waypoint in (
            {"position_m": poses[1][:3].tolist(), "quat_xyzw": [1, 0, 0, 0]}
            for poses in observed["brick_poses"]
        )
    ]
    actions = {"tool": [REACHABILITY] * 2, "judged": judged, "refused": ["[1]"] * 2}
    for kinds in (("tool", "judged"), ("judged", "tool"), ("refused", "tool")):
        _, rewards, terminated, truncated, infos = envs.step(
            tuple(actions[kind][index] for index, kind in enumerate(kinds))
        )
        assert_merged(infos)
        for index, kind in enumerate(kinds):
            info = env_info(infos, index)
            assert bool(info["call"]) == (kind == "judged"), info
            assert info["refusal"]["code"] == ("invalid_action" if kind == "refused" else "")
            tools = [reply["tool"] for reply in info["tool_results"]]
            assert tools == (["reachability"] if kind == "tool" else [])
            if kind == "judged":
                assert json.loads(info["call"])["outcome"] == "refused"
        assert not (rewards.any() or terminated.any() or truncated.any())
    assert list(infos["agent"]) == ["pre_grasp", "pre_grasp"]


class PromptAgent:
    """One env's agent, reading only what the vector env returns, as an LLM loop does: the
    prompt-only reference model (``reasoners/reference_model.py``) answers the conversation
    of the waiting agent's prompt (``info["prompt"]``) and the results of its tool calls.
    With ``tool_actions``, its tool calls go out as tool actions, one a step; without, in
    its answer (the session runs them)."""

    def __init__(self, tool_actions: bool) -> None:
        self.tool_actions = tool_actions
        self.messages: list[dict[str, str]] = []
        self.asked = ""  # the answer that asked for the tool calls under way
        self.queued: list[dict[str, Any]] = []  # its tool calls still to send
        self.replies: list[dict[str, Any]] = []  # and those replied to

    def ask(self, prompt: str) -> None:
        """A new question: the conversation starts over."""
        self.messages = [{"role": "user", "content": prompt}]

    def act(self) -> tuple[str, str]:
        """The next action, and its kind (tool or answer)."""
        if not self.queued:
            self.asked = reference_model.reply(self.messages)
            calls = json.loads(self.asked).get("tool_calls", [])
            if not (self.tool_actions and calls):
                return "answer", json.dumps({"answer": self.asked})
            self.queued = list(calls)
        call = self.queued.pop(0)
        return "tool", json.dumps({"tool": call["name"], "arguments": call.get("arguments", {})})

    def observe(self, info: dict[str, Any]) -> None:
        """What the step did: a judged answer brings the next question; tool results, once
        all of a turn's are in, go into the conversation as a model is sent them."""
        assert not info["refusal"]["code"], info["refusal"]
        if info["call"]:
            self.ask(info["prompt"])
            return
        self.replies += info["tool_results"]
        if self.replies and not self.queued:
            results = [
                {"tool": reply["tool"], "result": reply["result"]}
                if reply["refusal"] is None
                else {"tool": reply["tool"], "error": reply["refusal"]["detail"]}
                for reply in self.replies
            ]
            self.messages += [
                {"role": "assistant", "content": self.asked},
                {"role": "user", "content": TOOL_RESULTS + json.dumps(results)},
            ]
            self.replies = []


@pytest.mark.slow  # two whole trials
@pytest.mark.timeout(600)
@pytest.mark.parametrize("mode", MODES)
def test_agents_that_read_only_the_vector_env_build_to_the_end_and_it_closes(
    mode: str, one_brick: Path
) -> None:
    """Env 0's agent sends its tool calls as tool actions while env 1's answers (with tool
    calls in its answers): mixed steps, each env to the end of its episode (the other one,
    autoreset, goes on with its next trial meanwhile), then close() ends both."""
    envs = gymnasium.make_vec(
        ENV_ID, num_envs=2, vectorization_mode=mode, pattern=str(one_brick), physics="precise"
    )
    processes = list(getattr(envs, "processes", ()))
    assert len(processes) == (2 if mode == "async" else 0)
    try:
        _, infos = envs.reset(seed=11)
        agents = [PromptAgent(tool_actions=True), PromptAgent(tool_actions=False)]
        for index, agent in enumerate(agents):
            agent.ask(env_info(infos, index)["prompt"])
        results: dict[int, dict[str, Any]] = {}
        returns, ended, kinds = np.zeros(2), np.zeros(2, dtype=bool), set()
        for _ in range(400):
            if len(results) == 2:
                break
            # An env that ended is reset by this step (Gymnasium's next-step autoreset): the
            # action is not used.
            moves = [("reset", "") if ended[i] else agent.act() for i, agent in enumerate(agents)]
            _, rewards, terminated, truncated, infos = envs.step(tuple(a for _, a in moves))
            assert_merged(infos)
            kinds.add(tuple(kind for kind, _ in moves))
            for index, agent in enumerate(agents):
                info = env_info(infos, index)
                if ended[index]:
                    assert (info["trial"], info["agent"]) == (1, "pre_grasp")
                    agent.ask(info["prompt"])
                    continue
                agent.observe(info)
                if index not in results:
                    returns[index] += rewards[index]
                    if terminated[index] or truncated[index]:
                        assert terminated[index] and info["result"], info
                        results[index] = json.loads(info["result"])
            ended = terminated | truncated
        assert sorted(results) == [0, 1], f"unfinished after 400 steps: {sorted(results)}"
    finally:
        envs.close()
    assert ("tool", "answer") in kinds
    for index, result in results.items():
        assert (result["success"], result["bricks_placed"], result["llm"]) == (True, 1, "gym")
        assert (result["seed"], result["trial"], returns[index]) == (11 + index, 0, 1.0)
    assert not any(process.is_alive() for process in processes)


@pytest.mark.timeout(120)
@pytest.mark.filterwarnings("ignore:.*ERROR:UserWarning")  # Gymnasium's log of the error
def test_an_error_in_a_worker_is_raised_and_close_still_returns() -> None:
    """An async worker whose env raises mid-trial (a seed Gymnasium refuses, in one env):
    the error comes back to the caller, and close() ends both workers and their trials."""
    envs = gymnasium.make_vec(ENV_ID, num_envs=2, vectorization_mode="async")
    processes = list(envs.processes)
    try:
        envs.reset(seed=0)
        envs.step((REACHABILITY, "[1]"))
        with pytest.raises(gymnasium.error.Error, match="Seed must be greater or equal to zero"):
            envs.reset(seed=[3, -1])
    finally:
        envs.close()
    assert [process.exitcode for process in processes] == [0, 0]
