"""The trial session core both outside doors use: a trial that waits for its caller, hands
the simulator over, and never leaves its thread blocked."""

from __future__ import annotations

import json
import math
import threading

import numpy as np
import pytest

from actionreasoning.agents.outputs import PreGraspAnswer
from actionreasoning.errors import ToolError
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.sim.scene import Scene
from actionreasoning.tools.contact import SlipEstimate
from actionreasoning.tools.geometry import AlignmentErrors
from actionreasoning.tools.grasp_plan import GraspOptions
from actionreasoning.tools.reach import ReachReport
from actionreasoning.tools.registry import GATE_MEASUREMENTS
from actionreasoning.trial.runner import TrialObserver
from actionreasoning.trial.session import AgentLabel, Conditions, SessionError, TrialSession

SPEC = Conditions.load("pyramid", tools="solve").spec(seed=0, trial=0)  # grasp_options


def trial_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name.startswith("trial ")]


def test_the_waiting_agents_turn_and_its_tools() -> None:
    with TrialSession(SPEC) as session:
        turn = session.turn()
        assert turn is not None and turn.agent == "pre_grasp" and turn.feedback == ""
        assert [tool.name for tool in turn.tools] == ["grasp_options"]
        assert turn.tools[0].input_schema["title"] == "GraspOptionsQuery"
        assert turn.answer_schema == PreGraspAnswer.model_json_schema()
        assert turn.state == session.request.state and turn.prompt == session.request.prompt
        reply = session.call_tool(
            "grasp_options", {"brick_id": 0, "target_index": 0, "descent_opening_m": 0.15}
        )
        assert reply.refusal is None
        assert GraspOptions.model_validate(reply.result).options


def test_the_gates_measurements_run_for_the_waiting_agent_and_are_logged_with_its_call() -> None:
    with TrialSession(SPEC) as session:
        turn = session.turn()
        assert [tool.name for tool in turn.measurements] == list(GATE_MEASUREMENTS)
        state = turn.state
        brick, target, tool = state.brick(0).pose, state.goal.targets[0].pose, state.robot.ee_pose
        pose = tool.model_dump(mode="json")
        reach = session.measure("reachability", {"pose": pose})
        assert reach.refusal is None and ReachReport.model_validate(reach.result).reachable
        errors = AlignmentErrors.model_validate(
            session.measure("alignment_errors", {"brick_id": 0, "target_index": 0}).result
        )
        planar = math.dist(brick.position_m[:2], target.position_m[:2])
        assert errors.e_xy_norm_m == pytest.approx(planar)
        slip = SlipEstimate.model_validate(session.measure("slip_estimate", {"brick_id": 0}).result)
        lever = math.dist(brick.position_m, tool.position_m)
        assert math.hypot(*slip.offset_in_gripper_m) == pytest.approx(lever)
        # The request's runner is the session's too; refusals are typed and run nothing.
        assert session.request.measure(
            "reachability", {"pose": pose}
        ) == ReachReport.model_validate(reach.result)
        refused = session.measure("grasp_options", {"brick_id": 0, "target_index": 0}).refusal
        assert refused.code == "unknown_tool" and "gates' measurements" in refused.detail
        far = {"position_m": [1e3, 0, 0.2], "quat_xyzw": [1, 0, 0, 0]}
        for name, arguments, detail in (
            ("reachability", {"pose": far}, "more than 100 m away"),
            ("reachability", {"pose": {**pose, "quat_xyzw": [0, 0, 0, 0]}}, "unit quaternion"),
            ("alignment_errors", {"brick_id": 0, "target_index": 99}, "99"),
            ("slip_estimate", {"brick_id": 0, "extra": 1}, "Extra inputs"),
        ):
            refused = session.measure(name, arguments).refusal
            assert refused.code == "tool_error" and detail in refused.detail, (name, refused)
        assert session.measure("slip_estimate", [0]).refusal.code == "tool_error"  # type: ignore[arg-type]
        assert session.turn().agent == "pre_grasp" and session.turn().state == state
        run = session.close()
    assert run is not None
    first = run.transcript[0]
    assert [record.name for record in first.tool_calls] == [
        "reachability", "alignment_errors", "slip_estimate", "reachability", "grasp_options",
        "reachability", "reachability", "alignment_errors", "slip_estimate",
    ]  # fmt: skip
    assert first.tool_calls[0].result == reach.result and first.tool_calls[4].error


def test_an_answer_with_tool_calls_runs_them_and_the_agent_still_waits() -> None:
    with TrialSession(SPEC) as session:
        call = {"name": "grasp_options", "arguments": {"brick_id": 0, "target_index": 0}}
        missing = {**call, "arguments": {"brick_id": 99, "target_index": 0}}
        reply = session.answer(json.dumps({"tool_calls": [call, missing]}))
        assert reply.call is None and reply.refusal is None
        assert reply.tools[0].result is not None and reply.tools[0].refusal is None
        assert reply.tools[1].refusal.code == "tool_error"
        assert "no brick with id 99" in reply.tools[1].refusal.detail
        assert session.turn().agent == "pre_grasp"
        assert session.answer(b"{}").refusal.code == "invalid_answer"  # type: ignore[arg-type]
        refused = session.answer('{"brick_id": "one"}').refusal
        assert refused.code == "invalid_answer" and "brick_id" in refused.detail
        run = session.close()
    assert run is not None
    first = run.transcript[0]
    assert (first.outcome, len(first.tool_calls)) == ("failed", 2)
    assert first.repairs == [refused.detail]


def test_a_request_answers_through_the_session_and_goes_stale_once_answered() -> None:
    with TrialSession(SPEC) as session:
        request = session.request
        reply = BuiltinReasoner().decide(request)  # its tool calls run in the trial
        assert session.run is None
        judged = session.answer(json.dumps(reply.answer.model_dump(mode="json")))
        assert judged.call is not None and judged.call.outcome == "accepted"
        assert [tool.name for tool in judged.call.tool_calls] == ["grasp_options"]
        assert session.turn().agent == "descent"
        with pytest.raises(SessionError, match="answered"):
            request.call_tool("grasp_options", {"brick_id": 0, "target_index": 0})
        with pytest.raises(SessionError, match="answered"):
            request.measure("slip_estimate", {"brick_id": 0})
        assert session.request.measure("slip_estimate", {"brick_id": 0}).brick_id == 0
        with pytest.raises(ToolError, match="not in the knowledge base"):
            session.request.call_tool("grasp_options", {"brick_id": 0, "target_index": 0})


def test_closing_ends_the_trial_as_abandoned_and_its_thread() -> None:
    session = TrialSession(SPEC, agent=AgentLabel.MCP)
    assert session.in_scene(lambda scene: scene.ticks) > 0
    with pytest.raises(ZeroDivisionError):
        session.in_scene(lambda scene: 1 / 0)  # the caller's error, raised at the caller
    assert session.placed == 0
    run = session.close()
    assert run is not None and session.done and not trial_threads()
    assert run.result.failure.reason == "abandoned" and run.result.failure.agent == "pre_grasp"
    assert run.result.llm == "mcp" and run.result.bricks_placed == session.placed == 0
    with pytest.raises(SessionError, match="final picture was not kept"):
        session.picture()
    assert session.close() is run
    assert session.answer("{}").refusal.code == "trial_over"
    assert session.call_tool("grasp_options", {}).refusal.code == "trial_over"
    assert session.turn() is None and session.request is None
    with pytest.raises(SessionError, match="ended"):
        session.in_scene(lambda scene: scene.ticks)


def test_the_picture_is_the_overview_of_the_scene_now_and_of_the_final_scene() -> None:
    with TrialSession(SPEC, final_picture=True) as session:
        now = session.picture()
        assert now.shape == (360, 480, 3) and now.dtype == np.uint8
        assert len(np.unique(now.reshape(-1, 3), axis=0)) > 10  # a picture, not a blank
    assert session.picture().shape == now.shape


def test_a_trial_that_crashes_raises_at_the_caller_and_leaves_no_thread() -> None:
    class Broken(TrialObserver):
        def start(self, scene: Scene) -> None:
            raise RuntimeError("observer bug")

    with pytest.raises(RuntimeError, match="observer bug"):
        TrialSession(SPEC, [Broken()])
    assert not trial_threads()


def test_a_session_dropped_unclosed_ends_its_trial() -> None:
    session = TrialSession(SPEC)
    thread = next(iter(trial_threads()))
    del session
    thread.join(timeout=60)
    assert not thread.is_alive()
