"""Output directories under abuse, as a user meets it: `demo` into a directory of one's own,
two runs into one directory, a full disk, hand-edited result lines. Real processes, real
files, a real full file system where the machine lets one be mounted."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from conftest import assert_clean_error, cli

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}


@pytest.fixture(scope="module")
def one_brick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("pattern") / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


def eval_args(pattern: Path, out: Path, *extra: str, trials: int = 2) -> list[str]:
    return [
        "eval", "--method", "classical", "--pattern", str(pattern), "--trials", str(trials),
        "--out", str(out), *extra,
    ]  # fmt: skip


@pytest.fixture(scope="module")
def reference(one_brick: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Classical trials of the one-brick pattern, written undisturbed: enough lines to fill
    more than a file size limit a trial can run under."""
    out = tmp_path_factory.mktemp("reference") / "run"
    result = cli(*eval_args(one_brick, out, trials=24))
    assert result.returncode == 0, result.stderr
    return out


def lines_of(out: Path) -> list[bytes]:
    return (out / "results.jsonl").read_bytes().splitlines(keepends=True)


def first_trials_of(reference: Path, out: Path, count: int) -> None:
    """``out`` as the reference run was after its first ``count`` trials."""
    out.mkdir()
    shutil.copy(reference / "run.json", out / "run.json")
    (out / "results.jsonl").write_bytes(b"".join(lines_of(reference)[:count]))


def tree(directory: Path) -> dict[str, bytes]:
    """Every file under ``directory`` with its content."""
    files = (path for path in directory.rglob("*") if path.is_file())
    return {str(path.relative_to(directory)): path.read_bytes() for path in files}


# 7. hand-edited result lines


def test_a_whole_last_line_without_its_newline_is_kept_by_eval_and_report(
    one_brick: Path, reference: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    first_trials_of(reference, out, 2)
    whole = (out / "results.jsonl").read_bytes()
    (out / "results.jsonl").write_bytes(whole.rstrip(b"\n"))
    shown = cli("report", str(out), "--out", str(tmp_path / "report"))
    assert shown.returncode == 0, shown.stderr
    successes = sum(json.loads(line)["success"] for line in lines_of(reference)[:2])
    assert f"{successes}/2 ok" in shown.stdout
    resumed = cli(*eval_args(one_brick, out))
    assert resumed.returncode == 0, resumed.stderr
    assert "resuming: 2 of 2 trials" in resumed.stdout
    assert (out / "results.jsonl").read_bytes() == whole


@pytest.mark.parametrize("edited", [-1, 1, 5])
def test_an_edited_trial_index_is_refused_naming_the_line(
    one_brick: Path, reference: Path, tmp_path: Path, edited: int
) -> None:
    out = tmp_path / "run"
    first_trials_of(reference, out, 0)
    line0, line1 = lines_of(reference)[:2]
    copy = json.loads(line1)
    copy["trial"] = edited  # a third line: trial 1 copied, or trial 1 renumbered
    (out / "results.jsonl").write_bytes(line0 + line1 + json.dumps(copy).encode() + b"\n")
    where = f"{out / 'results.jsonl'} line 3"
    assert_clean_error(cli(*eval_args(one_brick, out, trials=3)), where)
    assert_clean_error(cli("report", str(out), "--out", str(tmp_path / "report")), where)
