"""`report` groups runs by their run.json conditions and pattern content, never by a name or
a path string: runs made by real `eval` commands under other budgets, fallbacks or pattern
files are shown apart, the same directory or pattern file given two ways is one thing, and
trials that collide are counted once only when their lines agree."""

from __future__ import annotations

import csv
import json
import shutil
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from conftest import SMALL_PATTERN, assert_clean_error, cli
from test_llm_faults import ONE_BRICK, FaultServer

#: Every test runs real trials (classical, or the agents asking a model server).
pytestmark = pytest.mark.slow


def classical(out: Path, *extra: str, pattern: str = "small.json", cwd: Path) -> Path:
    """One classical trial (or what ``extra`` asks for) of a pattern file, under precise
    physics, where the script succeeds."""
    result = cli(
        "eval", "--method", "classical", "--pattern", pattern, "--trials", "1",
        "--physics", "precise", "--out", str(out), *extra, cwd=cwd,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return out


def report(*runs: Path, out: Path, cwd: Path | None = None) -> tuple[list[dict], str, str]:
    """The CSV rows of `report RUNS` but averages, what it printed, and table.md."""
    result = cli("report", *map(str, runs), "--out", str(out), cwd=cwd)
    assert result.returncode == 0, result.stderr
    rows = [r for r in csv.DictReader((out / "table.csv").open()) if r["pattern"] != "Average"]
    return rows, result.stdout, (out / "table.md").read_text()


def successes(rows: list[dict]) -> dict[tuple[str, str], str]:
    return {(r["method"], r["pattern"]): f"{r['successes']}/{r['trials']}" for r in rows}


@pytest.fixture
def work(tmp_path: Path) -> Path:
    (tmp_path / "small.json").write_text(json.dumps(SMALL_PATTERN))
    return tmp_path


def test_runs_under_other_budgets_are_two_rows_in_either_order(work: Path) -> None:
    full = classical(work / "r_full", cwd=work)
    short = classical(work / "r_short", "--max-steps", "2000", cwd=work)
    expected = {
        ("classical, precise [budget.max_steps=400000]", "small"): "1/1",
        ("classical, precise [budget.max_steps=2000]", "small"): "0/1",
    }
    for order, out in (((short, full), "one"), ((full, short), "two")):
        rows, printed, markdown = report(*order, out=work / out)
        assert successes(rows) == expected
        failed = "0/1 (0 %, 95 % CI 0–79 %)"
        assert f"| classical, precise [budget.max_steps=2000] | {failed} | {failed} |" in markdown
        assert "[budget.max_steps=2000]" in printed  # not taken for rich markup
        html = (work / out / "report.html").read_text()
        for text in (printed, markdown, html):
            assert "Rows differ in run.json: budget.max_steps." in text


@contextmanager
def hostile_server() -> Iterator[FaultServer]:
    """A model server on loopback whose every answer is refused, so only the fallback builds."""
    server = FaultServer("hostile")
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    try:
        yield server
    finally:
        server.shutdown()
        server.server_close()


def agents(out: Path, server: FaultServer, *extra: str) -> Path:
    """One trial of the agents on one brick, asking ``server``."""
    pattern = out.parent / "one.json"
    pattern.write_text(json.dumps(ONE_BRICK))
    host, port = server.server_address[:2]
    result = cli(
        "eval", "--pattern", str(pattern), "--trials", "1", "--out", str(out),
        "--llm", "openai:fault", "--base-url", f"http://{host}:{port}/v1", "--repairs", "1",
        *extra,
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    return out


def test_runs_with_and_without_the_fallback_are_two_rows_in_either_order(tmp_path: Path) -> None:
    with hostile_server() as server:
        no_fallback = agents(tmp_path / "r_nofb", server)
        fallback = agents(tmp_path / "r_fb", server, "--fallback", "builtin")
    expected = {
        ("agents (openai:fault, tools check), paper [llm.fallback=false]", "one"): "0/1",
        ("agents (openai:fault, tools check), paper [llm.fallback=true]", "one"): "1/1",
    }
    for order, out in (((no_fallback, fallback), "one"), ((fallback, no_fallback), "two")):
        rows, printed, markdown = report(*order, out=tmp_path / out)
        assert successes(rows) == expected
        for text in (printed, markdown):
            assert "Rows differ in run.json: llm.fallback." in text


def test_a_pattern_file_edited_between_runs_is_a_second_column(work: Path) -> None:
    before = classical(work / "before", cwd=work)
    edited = {**SMALL_PATTERN, "origin": [0.5, 0.3, 0.0]}
    (work / "small.json").write_text(json.dumps(edited))
    after = classical(work / "after", cwd=work)
    hashes = [json.loads((d / "run.json").read_text())["pattern_sha256"] for d in (before, after)]
    assert hashes[0] != hashes[1]
    rows, _, markdown = report(before, after, out=work / "report")
    assert successes(rows) == {
        ("classical, precise", f"small ({hashes[0][:8]})"): "1/1",
        ("classical, precise", f"small ({hashes[1][:8]})"): "1/1",
    }
    assert f"small: 2 different pattern files (pattern_sha256 {hashes[0][:8]}" in markdown


def test_one_pattern_file_given_two_ways_is_one_column(work: Path) -> None:
    dotted = classical(work / "dotted", pattern="./small.json", cwd=work)
    plain = classical(work / "plain", "--seed", "1", cwd=work)
    rows, _, _ = report(dotted, plain, out=work / "report")
    assert successes(rows) == {("classical, precise", "small"): "2/2"}


def test_one_directory_given_two_ways_is_read_once(work: Path) -> None:
    classical(work / "run", cwd=work)
    (work / "link").symlink_to(work / "run")
    rows, printed, markdown = report(
        Path("run"), Path("./run/"), work / "link", out=work / "report", cwd=work
    )
    assert "counted once" not in printed + markdown  # no trial was found twice
    assert "1 run directory: <code>" in (work / "report" / "report.html").read_text()
    assert successes(rows) == {("classical, precise", "small"): "1/1"}


def test_the_same_trial_in_two_directories_with_identical_lines_is_counted_once(
    work: Path,
) -> None:
    first = classical(work / "first", cwd=work)
    again = classical(work / "again", pattern="./small.json", cwd=work)  # same seed: same trial
    copy = work / "copy"
    shutil.copytree(first, copy)
    rows, printed, markdown = report(first, again, copy, out=work / "report")
    assert successes(rows) == {("classical, precise", "small"): "1/1"}
    assert (
        "classical, precise on small: 2 trial lines are also in another directory, "
        "identical: each counted once" in markdown
    )
    assert "each counted once" in printed


def test_the_same_trial_in_two_directories_with_other_results_is_refused(tmp_path: Path) -> None:
    with hostile_server() as server:  # a model's latency differs from run to run
        first, second = agents(tmp_path / "a", server), agents(tmp_path / "b", server)
    assert (first / "results.jsonl").read_text() != (second / "results.jsonl").read_text()
    result = cli("report", str(first), str(second), "--out", str(tmp_path / "report"))
    assert_clean_error(
        result,
        "trial 0 of seed 0",
        f"{first / 'results.jsonl'} and {second / 'results.jsonl'}",
        "different results",
    )


def test_lines_of_another_run_under_a_run_json_are_refused(work: Path) -> None:
    """Lines of seed 0 appended under a run.json of seed 7 (as two runs into one --out left
    them) are not reported as seed 7."""
    zero = classical(work / "zero", "--trials", "2", cwd=work)
    seven = classical(work / "seven", "--seed", "7", cwd=work)
    second = (zero / "results.jsonl").read_text().splitlines(keepends=True)[1]
    with (seven / "results.jsonl").open("a") as sink:
        sink.write(second)
    result = cli("report", str(seven), "--out", str(work / "report"))
    assert_clean_error(
        result, f"{seven / 'results.jsonl'} line 2", "seed 0", f"{seven / 'run.json'} says 7"
    )


def test_results_without_a_run_json_are_refused(work: Path) -> None:
    run = classical(work / "run", cwd=work)
    (run / "run.json").unlink()
    result = cli("report", str(run), "--out", str(work / "report"))
    assert_clean_error(result, f"{run} holds results.jsonl but no run.json")
