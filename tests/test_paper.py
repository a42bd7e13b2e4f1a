"""`actionreasoning paper`: Table I's protocol in one command, resumable, with the paper's
rows beside ours."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from conftest import cli

from actionreasoning.report.paper_rows import PAPER_TABLE_I
from actionreasoning.runs.paper import METHODS, PATTERNS


@pytest.mark.slow  # twelve trials
def test_two_trials_write_the_three_methods_table_i_beside_the_papers(tmp_path: Path) -> None:
    out = tmp_path / "paper"
    first = cli("paper", "--trials", "2", "--out", str(out))
    assert first.returncode == 0, first.stderr
    for method in METHODS:
        for pattern in PATTERNS:
            run = out / "runs" / f"{method}-{pattern}"
            lines = [json.loads(x) for x in (run / "results.jsonl").read_text().splitlines()]
            assert [(x["method"], x["pattern"], x["trial"], x["seed"]) for x in lines] == [
                (str(method), pattern, k, 0) for k in range(2)
            ]
            assert {x["physics"] for x in lines} == {"paper"}
    table = (out / "report" / "table.md").read_text()
    for method in METHODS:
        assert f"| {method} (builtin, tools check), paper |" in table or (
            f"| {method}, paper |" in table
        )
    rows = [x for x in (out / "report" / "paper.md").read_text().splitlines() if x[:2] == "| "]
    labels = [row.split(" | ")[0][2:] for row in rows[1:]]
    assert labels[-2:] == list(PAPER_TABLE_I)
    assert [label.replace(",", " ").split()[0] for label in labels[:3]] == [str(m) for m in METHODS]
    assert rows[-1].endswith("| 0.703 | 0.637 | 88.03 |")
    again = cli("paper", "--trials", "2", "--out", str(out))  # resumes: nothing new to run
    assert again.returncode == 0, again.stderr
    assert again.stdout.count("resuming: 2 of 2 trials already in results.jsonl") == 6
    assert "Traceback" not in again.stdout + again.stderr
