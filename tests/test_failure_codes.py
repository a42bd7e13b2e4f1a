"""The failure codes are one enum, records.FailureCode: results store its values, and the
table in docs/robustness.md, summaries and reports print its meanings."""

from __future__ import annotations

import pytest
from conftest import doc_table
from pydantic import ValidationError

from actionreasoning.records import Failure, FailureClass, FailureCode
from actionreasoning.trial.results import BrickResult
from actionreasoning.trial.runner import misplaced
from actionreasoning.world.success import SuccessRule


def test_the_docs_table_is_the_enum_in_order() -> None:
    rows = doc_table("robustness.md", "## Failure codes", "| code | class | meaning |")
    assert rows == [(code.value, code.failure_class, code.meaning) for code in FailureCode]


#: What the world does to a brick after accepted answers (issue 37): every other code is
#: the answers' (or the model server's, which owed them).
PHYSICAL_EVENTS = {
    "grasp_slip": "slip or roll in the hand past the re-grasps",
    "no_brick_left": "every brick left toppled or fell on others",
    "placement_misaligned": "a set-down the forecast accepted rolled off its slot",
    "physics_blowup": "the simulation blew up or flung a brick",
    "misplaced": "a brick moved off after its set-down was accepted",
    "not_at_rest": "a brick still moving at the end",
}


@pytest.mark.parametrize("code", list(FailureCode))
def test_every_failure_code_has_one_class_physics_exactly_for_physical_events(
    code: FailureCode,
) -> None:
    expected = FailureClass.PHYSICS if code in PHYSICAL_EVENTS else FailureClass.REASONING
    assert code.failure_class is expected


def test_a_summary_counts_failures_by_class_every_class_present() -> None:
    from test_run_dir import result

    from actionreasoning.runs.summary import summarize, summary_markdown

    reasons = [FailureCode.GRASP_SLIP, FailureCode.COLLISION, FailureCode.MISPLACED]
    results = [result(0, success=True)] + [
        result(trial, success=False).model_copy(
            update={"failure": Failure(reason=reason, agent=None, detail="x")}
        )
        for trial, reason in enumerate(reasons, start=1)
    ]
    summary = summarize(results, wall_time_s=1.0)
    assert summary.failure_classes == {FailureClass.REASONING: 1, FailureClass.PHYSICS: 2}
    assert "Failures by class: reasoning 1, physics 2." in summary_markdown(summary)
    clean = summarize([result(0, success=True)], wall_time_s=1.0)
    assert clean.model_dump(mode="json")["failure_classes"] == {"reasoning": 0, "physics": 0}


def test_a_failure_reads_and_writes_its_code_as_the_plain_string() -> None:
    line = '{"reason":"grasp_slip","agent":"lift","detail":"re-grasp budget spent"}'
    failure = Failure.model_validate_json(line)
    assert failure.reason is FailureCode.GRASP_SLIP
    assert failure.model_dump_json() == line
    assert Failure(reason=FailureCode.GRASP_SLIP, agent="lift", detail="re-grasp budget spent") == (
        failure
    )


def test_an_unknown_code_is_refused_naming_it() -> None:
    with pytest.raises(ValidationError, match="grasp_slipped"):
        Failure(reason="grasp_slipped", detail="")  # type: ignore[arg-type]


def test_summaries_explain_each_code_from_the_enum() -> None:
    from test_run_dir import result

    from actionreasoning.runs.summary import summarize, summary_markdown

    results = [result(trial, success=trial == 0) for trial in range(3)]
    summary = summarize(results, wall_time_s=1.0)
    assert summary.failures == {FailureCode.MISPLACED: 2}
    row = f"| `misplaced` | physics | {FailureCode.MISPLACED.meaning} | 2 | 1 |"
    assert row in summary_markdown(summary)


def test_a_misplaced_build_names_the_brick_furthest_past_the_rule() -> None:
    """Seen on a wall (seed 0, trial 3): brick 0 was further off (0.64 cm, 2.67 deg, inside
    the rule), brick 4 turned 5.17 deg (outside); the detail must name brick 4."""
    rule = SuccessRule()  # 2 cm, 5 deg

    def brick(id_: int, offset_cm: float, rotation_deg: float) -> BrickResult:
        return BrickResult(
            id=id_, size=(0.2, 0.095, 0.06), target_position=(0.5, 0.0, 0.03),
            target_orientation=(0, 0, 0, 1), final_position=(0.5, 0.0, 0.03),
            final_orientation=(0, 0, 0, 1), center_offset_cm=offset_cm,
            rotation_error_deg=rotation_deg, symmetric_rotation_error_deg=rotation_deg, iou=0.9,
        )  # fmt: skip

    bricks = [brick(0, 0.64, 2.67), brick(4, 0.62, 5.17), brick(7, 0.13, 0.16)]
    failure = misplaced(bricks, rule)
    assert failure.reason is FailureCode.MISPLACED
    assert failure.detail == (
        "1 of 3 bricks outside 2.0 cm / 5.0 deg; worst brick 4: 0.62 cm, 5.17 deg"
    )
    assert rule.excess(bricks[1]) == pytest.approx(5.17 / 5.0)
    assert rule.excess(brick(1, 3.0, 1.0)) == pytest.approx(1.5)
