"""Drive ``actionreasoning/BrickStack-v0`` with the built-in reasoner as the outside agent,
and check that the episode gives the metrics ``actionreasoning eval`` gives that trial.

Every tool call and every answer of the built-in reasoner goes through ``env.step`` as
JSON text, exactly as an outside agent's would: the reasoner reads the structured form of
the waiting agent's request (``env.unwrapped.session.request``: what ``info["prompt"]``
says, as objects), its tool calls are steps whose results it reads from ``info``, and its
answer is the step that moves the arm.

    python examples/gym_builtin.py --pattern pyramid --seed 0 --trial 0
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from typing import Any

import gymnasium

import actionreasoning.gym_env
from actionreasoning.errors import ToolError
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.tools.base import ToolModel
from actionreasoning.tools.registry import TOOLS
from actionreasoning.trial.runner import run_trial

#: The fields of a results.jsonl line that say what the trial did.
METRICS = ("success", "bricks_placed", "bricks", "metrics", "failure", "sim_steps", "decisions")


def drive(env: gymnasium.Env, seed: int, trial: int, verbose: bool = False) -> tuple[dict, float]:
    """Run trial ``trial`` of run seed ``seed`` with the built-in reasoner's answers; the
    trial's result line (as a dict) and the episode's return."""
    _, info = env.reset(seed=seed, options={"trial": trial})
    policy, episode_return = BuiltinReasoner(), 0.0

    def step(action: dict[str, Any]) -> dict[str, Any]:
        nonlocal episode_return
        _, reward, _, truncated, info = env.step(json.dumps(action))
        assert not info["refusal"]["code"] and not truncated, info["refusal"]
        episode_return += reward
        return info

    def call_tool(name: str, arguments: Any) -> ToolModel:
        result = step({"tool": name, "arguments": arguments})["tool_results"][0]
        if result["refusal"] is not None:
            raise ToolError(result["refusal"]["detail"])
        return TOOLS[name].output_model.model_validate(result["result"])

    while not info["result"]:
        request = dataclasses.replace(env.unwrapped.session.request, call_tool=call_tool)
        answer = policy.decide(request).answer
        info = step({"answer": answer.model_dump(mode="json")})
        if verbose:
            call = json.loads(info["call"])
            gates = ", ".join(
                f"{g['gate']} {'pass' if g['passed'] else 'FAIL'}" for g in call["gates"]
            )
            print(f"{call['agent']:>10} brick {call['brick']}: {call['outcome']}  {gates}")
    return json.loads(info["result"]), episode_return


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pattern", default="pyramid")
    parser.add_argument("--physics", default="paper")
    parser.add_argument("--noise", default="none")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--trial", type=int, default=0)
    args = parser.parse_args()
    env = gymnasium.make(
        actionreasoning.gym_env.ENV_ID,
        pattern=args.pattern,
        physics=args.physics,
        noise=args.noise,
    )
    try:
        result, episode_return = drive(env, args.seed, args.trial, verbose=True)
    finally:
        env.close()
    print(f"episode return {episode_return:g} (bricks placed {result['bricks_placed']})")
    # What `actionreasoning eval --seed S` runs as its trial k: the same trial, its own agent.
    spec = env.unwrapped.conditions.spec(args.seed, args.trial)
    line = run_trial(spec).result.model_dump(mode="json")
    for field in METRICS:
        same = "same" if result[field] == line[field] else "DIFFERENT"
        print(f"{field:>14}: {same}  {json.dumps(line[field])[:70]}")
    if any(result[field] != line[field] for field in METRICS):
        raise SystemExit("the episode's metrics differ from eval's")


if __name__ == "__main__":
    main()
