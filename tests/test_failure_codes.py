"""The failure codes are one enum, records.FailureCode: results store its values, and the
table in docs/robustness.md, summaries and reports print its meanings."""

from __future__ import annotations

import pytest
from conftest import doc_table
from pydantic import ValidationError

from actionreasoning.records import Failure, FailureCode


def test_the_docs_table_is_the_enum_in_order() -> None:
    rows = doc_table("robustness.md", "## Failure codes", "| code | meaning |")
    assert rows == [(code.value, code.meaning) for code in FailureCode]


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
    row = f"| `misplaced` | {FailureCode.MISPLACED.meaning} | 2 | 1 |"
    assert row in summary_markdown(summary)
