"""Error categories: every check has one, every validation error carries one, transcripts and
results lines count refused answers by agent and category, and summaries and reports show
them (real PyBullet trials, the scripted FakeWorld, hand-made results lines)."""

from __future__ import annotations

import ast
import inspect
import json
from dataclasses import replace
from pathlib import Path
from types import ModuleType

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import SMALL_PATTERN, doc_table
from fake_world import FakeWorld
from test_hostile_outputs import HostileChat
from test_run_dir import manifest, result
from test_trial_config import run_config
from test_validation import AGENTS, DOWN, STATE, waypoint

from actionreasoning.agents import gates, orchestrator, plans, put_down
from actionreasoning.agents.answer_errors import AnswerCorruption, AnswerErrors, CorruptionKind
from actionreasoning.agents.error_kinds import CHECK_CATEGORIES, ErrorCategory, check_category
from actionreasoning.agents.orchestrator import Orchestrator
from actionreasoning.agents.transcript import AgentCall, Outcome
from actionreasoning.agents.validation import OutputError, parse_answer
from actionreasoning.reasoners.builtin import BuiltinReasoner
from actionreasoning.reasoners.llm import LLMLimits, LLMReasoner
from actionreasoning.report.build import build_report
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run import run_eval
from actionreasoning.runs.summary import summarize, summary_markdown
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.results import AnswerErrorCounts, TrialResult, refusals_of
from actionreasoning.trial.rules import Method
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import SceneSpec

C = ErrorCategory
K = CorruptionKind
#: The modules whose gates and pre-move checks refuse answers.
CHECKING = (gates, orchestrator, plans, put_down)

# --- every check has a category ---------------------------------------------------------


def _parameter_values(name: str, tree: ast.Module) -> set[str]:
    """The strings a function of ``tree`` gets for its parameter ``name``: from every call
    of it in ``tree`` (positional or keyword), else its default."""
    values = set()
    for function in ast.walk(tree):
        if not isinstance(function, ast.FunctionDef):
            continue
        parameters = [a.arg for a in function.args.args]
        if name not in parameters:
            continue
        index = parameters.index(name)
        defaults = dict(zip(parameters[::-1], function.args.defaults[::-1], strict=False))
        for call in ast.walk(tree):
            if not (isinstance(call, ast.Call) and ast.unparse(call.func) == function.name):
                continue
            keywords = {k.arg: k.value for k in call.keywords}
            given = call.args[index] if index < len(call.args) else keywords.get(name)
            values |= _strings(given if given is not None else defaults[name], tree)
    assert values, f"no value found for parameter {name}"
    return values


def _strings(node: ast.expr, tree: ast.Module) -> set[str]:
    """Every string ``node`` can be: a literal, a parameter's values, or an f-string of a
    parameter and a literal (``f"{prefix}reachable"``)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return {node.value}
    if isinstance(node, ast.Name):
        return _parameter_values(node.id, tree)
    if isinstance(node, ast.JoinedStr) and len(node.values) == 2:
        head, tail = node.values
        if isinstance(head, ast.FormattedValue) and isinstance(tail, ast.Constant):
            return {p + tail.value for p in _strings(head.value, tree)}
    raise AssertionError(f"a check name this test cannot read: {ast.unparse(node)}")


def check_names(modules: tuple[ModuleType, ...]) -> set[str]:
    """The name of every ``Check`` the modules can make, read from their source."""
    names = set()
    for module in modules:
        tree = ast.parse(inspect.getsource(module))
        for call in ast.walk(tree):
            if isinstance(call, ast.Call) and ast.unparse(call.func) == "Check":
                names |= _strings(call.args[0], tree)
    return names


def test_every_check_the_code_can_make_has_a_category_and_no_other_does() -> None:
    names = check_names(CHECKING)
    assert {"valid_answer", "close", "way_reachable", "retreat_clearance_m"} <= names
    assert {"set_down_reachable", "reachable", "clearance_m"} <= names
    assert names == set(CHECK_CATEGORIES)
    for name in names:
        assert check_category(name) is CHECK_CATEGORIES[name]


def test_a_check_without_a_category_fails_loudly() -> None:
    with pytest.raises(KeyError, match="'new_check_m' has no category"):
        check_category("new_check_m")
    source = ast.parse(
        'def f(prefix="a_"):\n    return Check(f"{prefix}new_m", 0, 1, True)\nf()\nf(prefix="b_")'
    )
    assert {"a_new_m", "b_new_m"} == {
        name
        for call in ast.walk(source)
        if isinstance(call, ast.Call) and ast.unparse(call.func) == "Check"
        for name in _strings(call.args[0], source)
    }


def test_every_kind_expects_a_category_with_a_meaning() -> None:
    assert {k: k.expected for k in K} == {
        K.SIGN_FLIP: C.MISALIGNMENT, K.YAW_90: C.MISALIGNMENT, K.YAW_180: C.MISALIGNMENT,
        K.CM_AS_M: C.FRAME_UNITS, K.INTO_OBSTACLE: C.COLLISION,
        K.SKIPPED_HOVER: C.PREMATURE_ACTION, K.TOO_FAST: C.DYNAMICS,
        K.WRONG_CHOICE: C.WRONG_CHOICE, K.MISSING_FIELD: C.SCHEMA,
        K.NEAR_OFFSET: C.MISALIGNMENT, K.NEAR_YAW: C.MISALIGNMENT,
    }  # fmt: skip
    assert all(c.meaning for c in C)


# --- validation errors carry theirs -----------------------------------------------------


@pytest.mark.parametrize(
    ("agent", "text", "category"),
    [
        ("lift", "close the gripper please", C.SCHEMA),
        ("lift", "x" * 30_000, C.SCHEMA),
        ("lift", json.dumps({"waypoint": {"position_m": "up", "quat_xyzw": DOWN}}), C.SCHEMA),
        ("lift", json.dumps({"waypoint": waypoint(), "run": 1}), C.SCHEMA),
        ("lift", json.dumps({"waypoint": waypoint(position=(5.0, 0, 0.2))}), C.FRAME_UNITS),
        ("lift", json.dumps({"waypoint": waypoint(quat=(1, 1, 0, 0))}), C.FRAME_UNITS),
        ("pre_grasp", json.dumps({"brick_id": 17}), C.HALLUCINATED_ID),
        ("pre_grasp", json.dumps({"target_index": 6}), C.HALLUCINATED_ID),
        ("lift", json.dumps({"tool_calls": [{"name": "teleport"}]}), C.HALLUCINATED_ID),
        (
            "placement",
            json.dumps({"tool_calls": [{"name": "held_pose", "arguments": {"brick_id": "x"}}]}),
            C.SCHEMA,
        ),
    ],
)  # fmt: skip
def test_each_validation_error_carries_its_category(agent: str, text: str, category: C) -> None:
    with pytest.raises(OutputError) as refused:
        parse_answer(text, AGENTS[agent], STATE)
    assert refused.value.category is category


# --- transcripts: the category of a call and of its repairs -----------------------------

BRICKS = sample_pick_poses(np.random.default_rng(0), 3, SceneSpec())
NOT_JSON, NO_BRICK = "no", json.dumps({"brick_id": 99})
OUTSIDE = json.dumps({"waypoint": waypoint(position=(5.0, 0, 0.2))})


def test_a_model_that_never_answers_validly_fails_as_its_last_repair(kinematics, wall) -> None:
    reasoner = LLMReasoner(HostileChat([NOT_JSON, NO_BRICK, OUTSIDE]), LLMLimits(repairs=2))
    built = Orchestrator(FakeWorld(wall, BRICKS, *kinematics), reasoner).build(wall)
    (call,) = built.transcript
    assert call.outcome is Outcome.FAILED and call.category is C.FRAME_UNITS
    assert call.repair_categories == [C.SCHEMA, C.HALLUCINATED_ID, C.FRAME_UNITS]
    assert call.refused_categories == call.repair_categories  # its last repair counted once
    assert refusals_of(built.transcript) == {
        "pre_grasp": {C.SCHEMA: 1, C.HALLUCINATED_ID: 1, C.FRAME_UNITS: 1}
    }


def test_repairs_are_counted_beside_the_answer_the_fallback_gave(kinematics, wall) -> None:
    one = wall.model_copy(update={"targets": wall.targets[:1]})
    chat = HostileChat([NOT_JSON])
    reasoner = LLMReasoner(chat, LLMLimits(repairs=0), fallback=BuiltinReasoner())
    built = Orchestrator(FakeWorld(one, BRICKS, *kinematics), reasoner).build(one)
    assert built.failure is None and all(c.fallback for c in built.transcript)
    assert {c.outcome for c in built.transcript} == {Outcome.ACCEPTED}
    assert all(c.category is None for c in built.transcript)
    counts = refusals_of(built.transcript)
    assert counts == {
        "pre_grasp": {C.SCHEMA: 1}, "descent": {C.SCHEMA: 1}, "grasp": {C.SCHEMA: 1},
        "lift": {C.SCHEMA: 1}, "placement": {C.SCHEMA: 2}, "release": {C.SCHEMA: 1},
    }  # fmt: skip


def test_a_server_failure_is_an_llm_failure_and_the_rule_of_a_call() -> None:
    call = AgentCall(
        call=0, agent="lift", brick=0, target=0, attempt=1, prompt_chars=1, answer={},
        repair_categories=[C.SCHEMA],
    )  # fmt: skip
    call.conclude(Outcome.FAILED, "timed out", C.LLM_FAILURE)
    assert call.refused_categories == [C.SCHEMA, C.LLM_FAILURE]
    call.conclude(Outcome.ACCEPTED)
    assert call.category is None and call.refused_categories == [C.SCHEMA]


# --- real trials with answer errors -----------------------------------------------------


def answer_error_run(out: Path, kind: CorruptionKind, bricks: int = 1) -> Path:
    """One trial of the agents on the first ``bricks`` of SMALL_PATTERN with every answer
    corrupted by ``kind``: agent 1 is refused until its budget is spent."""
    pattern = out.parent / "pattern.json"
    pattern.write_text(json.dumps({**SMALL_PATTERN, "bricks": SMALL_PATTERN["bricks"][:bricks]}))
    errors = AnswerErrors(rate=1.0, kinds=(kind,))
    config = run_config(pattern, out, TrialConfig(answer_errors=errors))
    run_eval(replace(config, method=Method.AGENTS, transcripts=True))
    return out


@pytest.fixture(scope="module")
def cm_as_m_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return answer_error_run(tmp_path_factory.mktemp("cm") / "run", K.CM_AS_M)


@pytest.mark.parametrize(
    ("kind", "bricks", "category"),
    [
        (K.CM_AS_M, 1, C.FRAME_UNITS),
        (K.MISSING_FIELD, 1, C.SCHEMA),
        (K.WRONG_CHOICE, 3, C.WRONG_CHOICE),  # the top brick's target, on nothing built yet
        (K.WRONG_CHOICE, 1, C.HALLUCINATED_ID),  # nothing to mistake: a brick id past the last
    ],
)
def test_a_trial_with_answer_errors_counts_their_refusals_by_category(
    tmp_path: Path, cm_as_m_run: Path, kind: CorruptionKind, bricks: int, category: C
) -> None:
    run = cm_as_m_run if kind is K.CM_AS_M else answer_error_run(tmp_path / "run", kind, bricks)
    (line,) = RunDir(run).results.read_text().splitlines()
    trial = TrialResult.model_validate_json(line)
    calls = [
        AgentCall.model_validate_json(text)
        for text in (run / "transcripts" / "trial_000.jsonl").read_text().splitlines()
    ]
    assert [(c.agent, c.outcome, c.category) for c in calls] == [
        ("pre_grasp", Outcome.REFUSED, category)
    ] * 3
    assert trial.refusals == {"pre_grasp": {category: 3}}
    assert trial.answer_errors == AnswerErrorCounts.of(calls)
    assert trial.answer_errors.refused_as == {kind: {category: 3}}
    assert json.loads(line)["refusals"] == {"pre_grasp": {str(category): 3}}
    summary = json.loads((run / "summary.json").read_text())
    assert summary["refusals"] == {"pre_grasp": {str(category): 3}}
    assert summary["answer_errors"]["refused_as"] == {str(kind): {str(category): 3}}
    markdown = (run / "summary.md").read_text()
    assert f"| Agent | `{category}` | Total |\n|---|---|---|\n| `pre_grasp` | 3 | 3 |" in markdown
    expected = f"`{kind.expected}`"
    assert f"| Kind | Expected | `{category}` | Total |" in markdown
    assert f"| `{kind}` | {expected} | 3 | 3 |" in markdown


def test_the_report_of_a_real_run_shows_its_refusals(cm_as_m_run: Path, tmp_path: Path) -> None:
    report = build_report([cm_as_m_run], tmp_path / "report")
    table = (tmp_path / "report" / "table.md").read_text()
    assert "| `pre_grasp` | 3 | 3 |" in table and "cm_as_m → frame_units 3" in table
    assert (tmp_path / "report" / "refusals.png") in [p for p, _ in report.plots]


# --- summaries and reports, counted by hand ---------------------------------------------


def line(trial: int, refusals: dict[str, dict[C, int]]) -> TrialResult:
    return result(trial).model_copy(update={"refusals": refusals})


LINES = [
    line(0, {"pre_grasp": {C.SCHEMA: 2}, "lift": {C.DYNAMICS: 1, C.MISALIGNMENT: 1}}),
    line(1, {"lift": {C.MISALIGNMENT: 3}, "descent": {C.COLLISION: 1}}),
    line(2, {}),
]


def test_lines_without_refusals_have_no_such_field_and_others_round_trip() -> None:
    assert "refusals" not in json.loads(LINES[2].model_dump_json())
    assert "refusals" in TrialResult.model_json_schema()["properties"]
    for trial in LINES:
        assert TrialResult.model_validate_json(trial.model_dump_json()) == trial


def test_summaries_sum_refusals_in_stage_order() -> None:
    summary = summarize(LINES, 1.0)
    assert summary.refusals == {
        "pre_grasp": {C.SCHEMA: 2},
        "descent": {C.COLLISION: 1},
        "lift": {C.MISALIGNMENT: 4, C.DYNAMICS: 1},
    }
    assert list(summary.refusals["lift"]) == [C.MISALIGNMENT, C.DYNAMICS]
    markdown = summary_markdown(summary)
    assert (
        "| Agent | `schema` | `misalignment` | `collision` | `dynamics` | Total |\n"
        "|---|---|---|---|---|---|\n"
        "| `pre_grasp` | 2 | 0 | 0 | 0 | 2 |\n"
        "| `descent` | 0 | 0 | 1 | 0 | 1 |\n"
        "| `lift` | 0 | 4 | 0 | 1 | 5 |\n"
    ) in markdown
    quiet = summarize(LINES[2:], 1.0)
    assert "refusals" not in json.loads(quiet.model_dump_json())
    assert "Refused" not in summary_markdown(quiet)


def test_the_answer_error_comparison_adds_up() -> None:
    flip = AnswerErrorCounts(
        corrupted=2, by_kind={K.SIGN_FLIP: 2}, caught_by={"a:b": 2},
        refused_as={K.SIGN_FLIP: {C.FRAME_UNITS: 1, C.MISALIGNMENT: 1}},
    )  # fmt: skip
    fast = AnswerErrorCounts(
        corrupted=1, by_kind={K.TOO_FAST: 1}, caught_by={"c:d": 1},
        refused_as={K.TOO_FAST: {C.DYNAMICS: 1}, K.SIGN_FLIP: {C.MISALIGNMENT: 2}},
    )  # fmt: skip
    assert (flip + fast).refused_as == {
        K.SIGN_FLIP: {C.MISALIGNMENT: 3, C.FRAME_UNITS: 1},
        K.TOO_FAST: {C.DYNAMICS: 1},
    }
    corrupted = AnswerCorruption(kind=K.SIGN_FLIP, detail="x", original={})
    calls = [
        AgentCall(
            call=i, agent="lift", brick=0, target=0, attempt=1, prompt_chars=1, answer={"a": 1},
            corruption=corrupted,
        )
        for i in range(2)
    ]  # fmt: skip
    calls[0].conclude(Outcome.REFUSED, "", C.FRAME_UNITS)
    calls[1].conclude(Outcome.ACCEPTED)
    counted = AnswerErrorCounts.of(calls)
    assert counted.refused_as == {K.SIGN_FLIP: {C.FRAME_UNITS: 1}}
    assert "refused_as" not in AnswerErrorCounts.of(calls[1:]).model_dump()


def test_a_report_has_a_refusal_table_and_the_chart(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text(manifest(physics=PRECISE).model_dump_json())
    lines = [*LINES, line(3, {"release": {C.UNREACHABLE: 2}})]
    (run / "results.jsonl").write_text("".join(r.model_dump_json() + "\n" for r in lines))
    report = build_report([run], tmp_path / "report")
    table = (tmp_path / "report" / "table.md").read_text()
    assert (
        "| Agent | `schema` | `misalignment` | `collision` | `unreachable` | `dynamics` | Total |\n"
        "|---|---|---|---|---|---|---|\n"
        "| `pre_grasp` | 2 | 0 | 0 | 0 | 0 | 2 |\n"
        "| `descent` | 0 | 0 | 1 | 0 | 0 | 1 |\n"
        "| `lift` | 0 | 4 | 0 | 0 | 1 | 5 |\n"
        "| `release` | 0 | 0 | 0 | 2 | 0 | 2 |\n"
    ) in table
    assert "![Refused answers by agent and error category](refusals.png)" in table
    chart = tmp_path / "report" / "refusals.png"
    assert (chart, "Refused and failed answers per agent, by error category") in report.plots
    image = iio.imread(chart)
    assert image.shape[0] > 200 and image.std() > 10
    html = (tmp_path / "report" / "report.html").read_text()
    assert "<h2>Refused answers</h2>" in html
    assert (
        "<tr><td>lift</td><td>0</td><td>4</td><td>0</td><td>0</td><td>1</td><td>5</td></tr>" in html
    )


def test_the_docs_table_is_the_enum_in_order() -> None:
    rows = doc_table(
        "agents-and-gates.md",
        "## Refused answers by category",
        "| category | meaning | refused by | the kind that expects it |",
    )
    assert [(category, meaning, kinds) for category, meaning, _, kinds in rows] == [
        (
            c.value,
            c.meaning,
            ", ".join(f"`{k}`" for k in CorruptionKind if k.expected is c) or "–",
        )
        for c in ErrorCategory
    ]
