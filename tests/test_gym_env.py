"""The Gymnasium environment actionreasoning/BrickStack-v0: Gymnasium's own checker, the
built-in reasoner's answers through it reproduce eval's line, and hostile actions get a
typed refusal in ``info`` while the arm stays where it is."""

from __future__ import annotations

import importlib.util
import json
import math
import re
from collections.abc import Iterator
from dataclasses import asdict
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from conftest import eval_lines
from gymnasium.utils.env_checker import check_env

import actionreasoning.gym_env
from actionreasoning.agents.answer_errors import CorruptionKind
from actionreasoning.errors import ActionReasoningError, ConfigError
from actionreasoning.gym_env import ENV_ID, MAX_EPISODE_STEPS, SCENARIOS, scenario_id
from actionreasoning.gym_env.env import INFO_TYPES, BrickStackEnv
from actionreasoning.gym_env.observation import BRICK_KEYS, MAX_ACTION_CHARS
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.trial.rules import Method
from actionreasoning.world.pictures import SHOWN_NAMES
from actionreasoning.world.scenarios import NOISE, PHYSICS, Scenario
from actionreasoning.world.scene_spec import FINGERTIPS_BEYOND_TCP_M, SceneSpec

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "gym_builtin.py"


def assert_typed(info: dict[str, Any]) -> None:
    """``info`` has the keys of INFO_TYPES, each of its type; ``refusal`` has code and detail."""
    assert {key: type(value) for key, value in info.items()} == INFO_TYPES, info
    assert {key: type(value) for key, value in info["refusal"].items()} == {
        "code": str,
        "detail": str,
    }


def example() -> Any:
    """examples/gym_builtin.py as a module."""
    spec = importlib.util.spec_from_file_location("gym_builtin", EXAMPLE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def env() -> Iterator[BrickStackEnv]:
    # The solve tier: these tests call grasp_options, which only it has.
    made = gymnasium.make(actionreasoning.gym_env.ENV_ID, pattern="pyramid", tools="solve")
    yield made.unwrapped
    made.close()


def test_check_env_passes_and_render_is_the_overview_picture() -> None:
    made = gymnasium.make(actionreasoning.gym_env.ENV_ID, render_mode="rgb_array")
    try:
        check_env(made.unwrapped)
        made.reset(seed=1)
        image = made.render()
        assert image.shape == (360, 480, 3) and image.dtype == np.uint8
        assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10  # a picture, not a blank
    finally:
        made.close()


@pytest.mark.parametrize("scenario", SCENARIOS, ids=str)
def test_every_builtin_scenario_makes_an_env_by_its_own_id_too(scenario: Scenario) -> None:
    """Made only (the scene is built on reset): its conditions are the scenario's, through
    the generic id and the scenario's own alike."""
    made = gymnasium.make(ENV_ID, **asdict(scenario))
    own = gymnasium.make(scenario_id(scenario))
    try:
        env = made.unwrapped
        assert isinstance(env, BrickStackEnv)
        config, goal = env.conditions.config, env.conditions.goal
        assert (env.conditions.pattern_name, goal.name) == (scenario.pattern, scenario.pattern)
        assert (config.physics, config.noise) == (PHYSICS[scenario.physics], NOISE[scenario.noise])
        assert env.observation_space["brick_poses"].shape == (len(goal.targets), 7)
        assert own.unwrapped.conditions == env.conditions
        assert own.spec is not None and own.spec.max_episode_steps == MAX_EPISODE_STEPS
    finally:
        made.close()
        own.close()


def test_the_ids_are_the_generic_one_and_one_per_builtin_scenario() -> None:
    ours = {env_id for env_id in gymnasium.registry if env_id.startswith("actionreasoning/")}
    assert ours == {ENV_ID, *map(scenario_id, SCENARIOS)} and len(ours) == len(SCENARIOS) + 1
    assert scenario_id(SCENARIOS[0]) == "actionreasoning/BrickStack-pyramid-paper-none-v0"


def test_reset_seed_and_trial_are_those_of_eval(env: BrickStackEnv) -> None:
    _, info = env.reset(seed=5)
    assert (info["seed"], info["trial"], info["agent"]) == (5, 0, "pre_grasp")
    assert (info["refusal"], info["call"], info["result"]) == ({"code": "", "detail": ""}, "", "")
    assert_typed(info)
    second, info = env.reset()
    assert (info["seed"], info["trial"]) == (5, 1)
    assert info["prompt"].startswith("# Agent 1 of 6")
    again, info = env.reset(seed=5, options={"trial": 1})
    assert (info["seed"], info["trial"]) == (5, 1)
    assert again["state"] == second["state"]
    assert np.array_equal(again["brick_poses"], second["brick_poses"])
    bricks = json.loads(again["state"])["bricks"]
    assert again["brick_poses"][2, :3].tolist() == bricks[2]["pose"]["position_m"]
    with pytest.raises(ConfigError, match="unknown reset options"):
        env.reset(options={"trials": 2})


@pytest.mark.slow  # two whole trials
def test_the_builtin_reasoners_answers_reproduce_the_eval_line(
    tmp_path: Path, small_pattern: Path
) -> None:
    line = json.loads(eval_lines(tmp_path / "eval", small_pattern, Method.AGENTS))
    made = gymnasium.make(actionreasoning.gym_env.ENV_ID, pattern=str(small_pattern))
    try:
        gym_builtin = example()
        result, episode_return = gym_builtin.drive(made, seed=3, trial=0)
    finally:
        made.close()
    for field in gym_builtin.METRICS:
        assert result[field] == line[field], field
    assert line["success"] and episode_return == line["bricks_placed"] == 3
    assert (result["llm"], line["llm"]) == ("gym", "builtin")


NAN_WAYPOINT = {"position_m": [float("nan"), -0.1, 0.2], "quat_xyzw": [1, 0, 0, 0]}
FAR_WAYPOINT = {"position_m": [2.5, -0.1, 0.2], "quat_xyzw": [1, 0, 0, 0]}


def answer(**fields: object) -> str:
    return json.dumps({"answer": {"brick_id": 0, "target_index": 0, **fields}})


@pytest.mark.parametrize(
    ("action", "code", "detail"),
    [
        ('{"answer": {"brick_id": 0,', "invalid_action", "not valid JSON"),
        ('{"answer": "{\\"brick_id\\": 0,"}', "invalid_answer", "not valid JSON"),
        ('{"answer": {"brick_id": ' + "9" * 5000 + "}}", "invalid_action", "4300 digits"),
        ('{"answer": "{\\"brick_id\\": ' + "9" * 5000 + '}"}', "invalid_answer", "4300 digits"),
        ('{"answer": {}, "tool": "grasp_options"}', "invalid_action", "an action is"),
        ("[1, 2]", "invalid_action", "an action is"),
        ('{"tool": "rm -rf /", "arguments": {}}', "unknown_tool", "not in the knowledge base"),
        ('{"tool": "collision_check", "arguments": {}}', "unknown_tool", "of pre_grasp"),
        ('{"tool": "grasp_options", "arguments": [1]}', "tool_error", "a JSON object"),
        (answer(waypoint=NAN_WAYPOINT), "invalid_answer", "finite number"),
        (answer(waypoint=FAR_WAYPOINT), "invalid_answer", "outside the workspace box"),
        (
            answer(tool_calls=[{"name": "reachability", "arguments": {}}]),
            "invalid_answer",
            "not one of your tools",
        ),
        (
            '{"tool": "grasp_options", "arguments": '
            '{"brick_id": 0, "target_index": 0, "descent_opening_m": NaN}}',
            "tool_error",
            "descent_opening_m",
        ),
    ],
)
def test_a_hostile_action_is_refused_and_the_arm_stays(
    env: BrickStackEnv, action: str, code: str, detail: str
) -> None:
    before, _ = env.reset(seed=0)
    ticks = env.session.in_scene(lambda scene: scene.ticks)
    observed, reward, terminated, truncated, info = env.step(action)
    assert info["refusal"]["code"] == code and detail in info["refusal"]["detail"], info
    assert (reward, terminated, truncated, info["call"]) == (0.0, False, False, "")
    assert_typed(info)
    assert info["agent"] == "pre_grasp" and observed["state"] == before["state"]
    assert env.session.in_scene(lambda scene: scene.ticks) == ticks


def test_hostile_tool_poses_are_refused_without_hanging_the_arm_model(env: BrickStackEnv) -> None:
    """Through the descent agent's collision check and the gates' reachability, which any
    agent may run: a huge number hung the IK, a zero quaternion crashed it."""
    env.reset(seed=0)
    accepted = BuiltinReasoner().decide(env.session.request).answer
    _, _, _, _, info = env.step(json.dumps({"answer": accepted.model_dump(mode="json")}))
    assert json.loads(info["call"])["outcome"] == "accepted" and info["agent"] == "descent"
    ticks = env.session.in_scene(lambda scene: scene.ticks)
    for tool in ("collision_check", "reachability"):
        for pose, detail in (
            ({"position_m": [1e308, 0.0, 0.3]}, "more than 100 m away"),
            ({"position_m": [0.5, 0.0, 0.3], "quat_xyzw": [0, 0, 0, 0]}, "unit quaternion"),
            ({"position_m": [0.5, 0.0, 0.3], "quat_xyzw": [1e300, 0, 0, 0]}, "unit quaternion"),
        ):
            action = {"tool": tool, "arguments": {"pose": pose}}
            _, reward, _, _, info = env.step(json.dumps(action))
            assert info["refusal"]["code"] == "tool_error" and detail in info["refusal"]["detail"]
            assert reward == 0.0 and info["agent"] == "descent"
    slip = {"tool": "slip_estimate", "arguments": {"brick_id": accepted.brick_id}}
    _, _, _, _, info = env.step(json.dumps(slip))
    assert info["refusal"] == {"code": "", "detail": ""} and info["agent"] == "descent"
    assert info["tool_results"][0]["result"]["brick_id"] == accepted.brick_id
    assert_typed(info)
    assert env.session.in_scene(lambda scene: scene.ticks) == ticks


def test_an_answer_a_gate_refuses_comes_back_with_its_checks_and_the_arm_stays(
    env: BrickStackEnv,
) -> None:
    observed, _ = env.reset(seed=0)
    ticks = env.session.in_scene(lambda scene: scene.ticks)
    other = observed["brick_poses"][1]  # approach brick 0 through the middle of brick 1
    waypoint = {"position_m": other[:3].tolist(), "quat_xyzw": [1, 0, 0, 0]}
    _, reward, terminated, _, info = env.step(answer(waypoint=waypoint))
    assert_typed(info)
    call = json.loads(info["call"])
    assert info["refusal"]["code"] == "" and call["outcome"] == "refused" and not terminated
    # A choice that can be built; an approach that is no hover over the brick it chose, refused
    # before it moves (sigma_1's path check is never reached).
    choice, plan = call["gates"]
    assert (choice["gate"], choice["passed"]) == ("pre_grasp_choice", True)
    assert plan["gate"] == "pre_grasp_plan" and not plan["passed"]
    failed = {c["name"]: c["value"] for c in plan["checks"] if not c["passed"]}
    top = observed["brick_poses"][0][2] + SceneSpec().brick_size_m[2] / 2
    hover = other[2] - FINGERTIPS_BEYOND_TCP_M - top
    assert failed["hover_clearance_m"] == pytest.approx(hover, abs=1e-5)
    assert call["feedback"].startswith("pre_grasp_plan failed: hover_clearance_m = ")
    assert info["agent"] == "pre_grasp" and reward == 0.0
    assert env.session.turn().feedback == call["feedback"]
    assert env.session.in_scene(lambda scene: scene.ticks) == ticks


def test_step_before_reset_and_after_the_end() -> None:
    env = BrickStackEnv()
    with pytest.raises(gymnasium.error.ResetNeeded):
        env.step('{"answer": {}}')
    env.reset(seed=0)
    env.session.close()
    _, reward, terminated, truncated, info = env.step('{"answer": {}}')
    assert info["refusal"]["code"] == "trial_over" and (terminated, truncated) == (True, False)
    assert json.loads(info["result"])["failure"]["reason"] == "abandoned" and reward == 0.0
    assert (info["agent"], info["prompt"], info["tools"], info["call"]) == ("", "", [], "")
    assert_typed(info)
    env.close()


@pytest.mark.parametrize("seconds", [math.nan, math.inf, 0.0, -1.0, True, "3"])
def test_a_wall_time_budget_that_cannot_bound_a_trial_is_refused(seconds: float) -> None:
    with pytest.raises(ConfigError, match=r"max_trial_s .*: give a positive, finite number"):
        gymnasium.make("actionreasoning/BrickStack-v0", max_trial_s=seconds)


def test_a_refused_reset_leaves_the_env_as_it_was(env: BrickStackEnv) -> None:
    env.reset(seed=3)
    with pytest.raises(ConfigError):
        env.reset(seed=True)  # type: ignore[arg-type]  # what a careless caller passes
    _, info = env.reset()
    assert (info["seed"], info["trial"]) == (3, 1)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"pattern": "p" * 300 + ".json"}, "pattern: file name too long (305 characters)"),
        ({"pattern": "a\0b.json"}, "pattern: contains a NUL byte"),
        ({"physics": "a\0b.json"}, "physics: contains a NUL byte"),
        ({"noise": "n" * 5000}, "noise: file name too long (5000 characters)"),
    ],
)
def test_a_path_no_file_can_have_is_refused(kwargs: dict[str, str], message: str) -> None:
    with pytest.raises(ActionReasoningError, match=re.escape(message)):
        gymnasium.make("actionreasoning/BrickStack-v0", **kwargs)


def test_a_pattern_too_tight_for_the_gates_is_refused_when_the_env_is_made(
    tmp_path: Path,
) -> None:
    from test_gates import TIGHT

    pattern = tmp_path / "tight.json"
    pattern.write_text(json.dumps(TIGHT))
    with pytest.raises(ActionReasoningError, match=r"wider than 4\.1 mm"):
        gymnasium.make(actionreasoning.gym_env.ENV_ID, pattern=str(pattern))


def test_a_trial_out_of_time_before_its_first_question_is_one_line_and_needs_a_reset() -> None:
    """1e-300 s is a positive, finite budget: the trial ends in its spawn settle. reset()
    says so in one line (it dumped the whole result), and step() asks for a reset (it
    raised a bare AssertionError)."""
    env = gymnasium.make(actionreasoning.gym_env.ENV_ID, max_trial_s=1e-300)
    try:
        with pytest.raises(ActionReasoningError) as ended:
            env.reset(seed=0)
        message = str(ended.value)
        assert message.startswith("trial 0 ended before an agent asked: time_budget (")
        assert "\n" not in message and len(message) < 300
        with pytest.raises(gymnasium.error.ResetNeeded):
            env.step('{"brick_id": 0}')
    finally:
        env.close()


PYRAMID = [(ENV_ID, {"pattern": "pyramid"}), (scenario_id(SCENARIOS[0]), {})]


@pytest.mark.parametrize(("env_id", "kwargs"), PYRAMID, ids=["generic", "scenario"])
def test_answer_errors_corrupt_the_callers_answers_as_eval_does(
    env_id: str, kwargs: dict[str, str]
) -> None:
    """The docs promise ``answer_errors`` over Gymnasium, by the generic id and a scenario's:
    at rate 1 the caller's answer is corrupted before its gate sees it, and the call says
    how."""
    made = gymnasium.make(env_id, **kwargs, answer_errors=1.0)
    env = made.unwrapped
    assert (
        env.conditions.pattern_name == "pyramid" and env.conditions.config.answer_errors.rate == 1
    )
    env.reset(seed=0)
    given = BuiltinReasoner().decide(env.session.request).answer.model_dump(mode="json")
    _, _, _, _, info = env.step(json.dumps({"answer": given}))
    corruption = json.loads(info["call"])["corruption"]
    assert corruption["original"] == given and corruption["kind"] in set(CorruptionKind)
    made.close()


@pytest.mark.parametrize("env_id", [ENV_ID, scenario_id(SCENARIOS[-1])])
@pytest.mark.parametrize("rate", [-0.1, 1.5, math.nan, True, "0.2"])
def test_an_answer_error_rate_outside_0_to_1_is_refused(env_id: str, rate: object) -> None:
    with pytest.raises(ConfigError, match=r"answer_errors .*: give a rate from 0 to 1"):
        gymnasium.make(env_id, answer_errors=rate)


def test_the_action_space_admits_every_action_the_env_accepts_and_nothing_it_refuses(
    env: BrickStackEnv,
) -> None:
    """Non-ASCII text (a model's rationale in degrees) and the longest action the env takes
    are in the space; a character or a length the space excludes is refused."""
    space = env.action_space
    env.reset(seed=0)
    decided = BuiltinReasoner().decide(env.session.request).answer.model_dump(mode="json")
    rationale = "wrist turned 90°, ±0.5 mm ✓ 👍"
    non_ascii = json.dumps({"answer": {**decided, "rationale": rationale}}, ensure_ascii=False)
    wrapped = json.dumps({"answer": decided})
    longest = wrapped[:-1] + " " * (MAX_ACTION_CHARS - len(wrapped)) + "}"
    assert len(longest) == MAX_ACTION_CHARS == space.max_length and not non_ascii.isascii()
    for action in (non_ascii, longest):
        assert space.contains(action)
        env.reset(seed=0)
        _, _, _, _, info = env.step(action)
        assert json.loads(info["call"])["outcome"] == "accepted", info["refusal"]
    env.reset(seed=0)
    for action, detail in (
        (longest + " ", f"more than {MAX_ACTION_CHARS}"),
        (non_ascii.replace("°", "\ud800"), "U+D800"),  # a lone surrogate: no UTF-8 for it
        (wrapped.replace(" ", "\x1b", 1), "U+001B"),  # a control character
        (wrapped.encode(), "not bytes"),
    ):
        assert not space.contains(action)
        _, _, _, _, info = env.step(action)  # type: ignore[arg-type]
        assert info["refusal"]["code"] == "invalid_action", info["refusal"]
        assert detail in info["refusal"]["detail"] and info["agent"] == "pre_grasp"


def test_with_pictures_each_observation_holds_them_inside_its_space() -> None:
    """observe="both": Gymnasium's checker passes; the pictures the waiting agent's call
    carries are arrays of the Dict space (depth in metres: the far ground corner 1.8 m below
    the top-down camera), and stay there after an answer a gate refuses as invalid."""
    made = gymnasium.make(ENV_ID, observe="both")
    try:
        check_env(made.unwrapped)
        shown, info = made.reset(seed=1)
        assert made.observation_space.contains(shown)
        assert list(shown["pictures"]) == list(SHOWN_NAMES) and "## Cameras" in info["prompt"]
        depth = shown["pictures"]["top_down.depth"]
        assert depth.dtype == np.float32 and depth[3, 3] == pytest.approx(1.8, abs=2e-3)
        after, _, _, _, refused = made.step(answer(brick_id=99))
        assert refused["refusal"]["code"] == "invalid_answer"
        assert made.observation_space.contains(after)
        assert np.array_equal(after["pictures"]["top_down.depth"], depth)
    finally:
        made.close()
    with pytest.raises(ConfigError, match="observe 'eyes': not one of state, image, both"):
        gymnasium.make(ENV_ID, observe="eyes")


def test_in_the_image_tier_no_brick_pose_is_observed_and_answers_name_bricks_by_place() -> None:
    """observe="image": the observation has the pictures but no brick array, and its state
    text no brick; an answer naming a brick by id is refused as a schema error (agent 1
    names none), and an approach over no brick is refused as naming nothing."""
    made = gymnasium.make(ENV_ID, observe="image")
    try:
        shown, info = made.reset(seed=1)
        assert made.observation_space.contains(shown)
        assert "pictures" in shown and not set(BRICK_KEYS) & set(shown)
        assert "bricks" not in json.loads(shown["state"]) and "Observation: image" in info["prompt"]
        assert "alignment_errors" not in info["prompt"]
        by_id = answer(waypoint={"position_m": [0.4, -0.3, 0.2], "quat_xyzw": [1, 0, 0, 0]})
        _, _, _, _, refused = made.step(by_id)
        assert refused["refusal"]["code"] == "invalid_answer"
        assert "brick_id" in refused["refusal"]["detail"]
        nothing = {"position_m": [0.3, 0.3, 0.2], "quat_xyzw": [1, 0, 0, 0]}
        action = json.dumps({"answer": {"target_index": 0, "waypoint": nothing}})
        _, _, _, _, judged = made.step(action)
        call = json.loads(judged["call"])
        assert (call["outcome"], call["category"]) == ("refused", "hallucinated_id")
        assert call["feedback"].startswith("pre_grasp_choice failed: brick_under_approach = 0")
    finally:
        made.close()
