"""Files a user names are read only when they are regular files of at most 1 MiB, and
parsed without a traceback however deep they nest: one line and exit code 2 otherwise."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
import yaml
from conftest import SMALL_PATTERN, assert_clean_error, cli

from actionreasoning.errors import ConfigError
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run_dir import read_results
from actionreasoning.world.config_files import MAX_FILE_BYTES, read_user_file
from actionreasoning.world.scenarios import load_noise, load_physics

#: The loaders of physics and noise files, by how their errors name the file.
LOADERS = {"physics file": load_physics, "noise file": load_noise}
#: A read that blocks (a FIFO) fails the test after this long.
HANG_S = 120
#: Bad files: how to make one at a path, and what its error says.
BAD_FILES = {
    "fifo": (os.mkfifo, "(a FIFO, not a regular file)"),
    "dev_zero": (
        lambda path: path.symlink_to("/dev/zero"),
        "(a character device, not a regular file)",
    ),
    "directory": (Path.mkdir, "(a directory, not a regular file)"),
    "large": (
        lambda path: path.write_text(" " * MAX_FILE_BYTES + "{}"),
        "(larger than 1 MiB)",
    ),
}  # fmt: skip


@pytest.mark.timeout(HANG_S)
@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_pattern_that_is_no_regular_file_or_too_large_is_refused_at_once(
    tmp_path: Path, case: str
) -> None:
    make, reason = BAD_FILES[case]
    path = tmp_path / f"{case}.yaml"
    make(path)
    out = tmp_path / "out"
    # Before: a FIFO blocked for ever (the timeout fails the test), /dev/zero filled memory.
    result = cli("eval", "--pattern", str(path), "--out", str(out))
    assert_clean_error(result, f"{path}: cannot read pattern file {reason}")
    assert not out.exists()


@pytest.mark.parametrize("what", sorted(LOADERS))
@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_physics_or_noise_file_that_is_no_regular_file_or_too_large_is_refused(
    tmp_path: Path, what: str, case: str
) -> None:
    make, reason = BAD_FILES[case]
    path = tmp_path / f"{case}.yaml"
    make(path)
    with pytest.raises(ConfigError) as info:
        LOADERS[what](str(path))
    assert str(info.value) == f"{path}: cannot read {what} {reason}"


NESTED = {
    "deep.json": "[" * 100_000 + "]" * 100_000,
    "deep_object.json": '{"a": ' * 100_000 + "1" + "}" * 100_000,
    "deep.yaml": "[" * 100_000 + "]" * 100_000,
    "deep_block.yaml": "- " * 100_000 + "x\n",
}


@pytest.mark.parametrize("name", sorted(NESTED))
def test_a_pattern_nested_100000_deep_is_refused_in_one_line(tmp_path: Path, name: str) -> None:
    path = tmp_path / name
    path.write_text(NESTED[name])
    kind = "JSON" if path.suffix == ".json" else "YAML"
    assert_clean_error(cli("pattern", str(path)), f"{path}: not valid {kind} (nested too deeply)")


@pytest.mark.parametrize("what", sorted(LOADERS))
@pytest.mark.parametrize("name", sorted(NESTED))
def test_a_physics_or_noise_file_nested_100000_deep_is_refused(
    tmp_path: Path, what: str, name: str
) -> None:
    path = tmp_path / name
    path.write_text(NESTED[name])
    kind = "JSON" if path.suffix == ".json" else "YAML"
    with pytest.raises(ConfigError) as info:
        LOADERS[what](str(path))
    assert str(info.value) == f"{path}: not valid {kind} (nested too deeply)"


@pytest.mark.timeout(HANG_S)
def test_the_pattern_command_refuses_a_fifo_too(tmp_path: Path) -> None:
    fifo = tmp_path / "pattern.json"
    os.mkfifo(fifo)
    result = cli("pattern", str(fifo))
    assert_clean_error(result, "pattern file (a FIFO, not a regular file)")


def test_a_file_of_exactly_the_limit_is_read(tmp_path: Path) -> None:
    path = tmp_path / "limit.json"
    text = json.dumps(SMALL_PATTERN)
    path.write_text(text + " " * (MAX_FILE_BYTES - len(text)))
    assert read_user_file(path, "pattern file") == path.read_bytes()


@pytest.mark.timeout(HANG_S)
def test_a_run_file_that_is_a_fifo_is_refused_on_resume(
    tmp_path: Path, small_pattern: Path
) -> None:
    out = tmp_path / "out"
    args = ["eval", "--method", "classical", "--pattern", str(small_pattern), "--out", str(out)]
    out.mkdir()
    (out / RunDir.RESULTS).write_text("{}\n")
    os.mkfifo(out / RunDir.MANIFEST)
    result = cli(*args, "--trials", "1")
    assert_clean_error(result, f"{out / RunDir.MANIFEST}: cannot read run file (a FIFO")
    assert (out / RunDir.RESULTS).read_text() == "{}\n"


def test_a_results_file_that_is_a_fifo_is_refused(tmp_path: Path) -> None:
    fifo = tmp_path / RunDir.RESULTS
    os.mkfifo(fifo)
    with pytest.raises(ConfigError, match="cannot read results file \\(a FIFO"):
        read_results(fifo)


@pytest.mark.timeout(HANG_S)
@pytest.mark.parametrize("case", ["fifo", "dev_zero", "directory"])
def test_a_recording_that_is_no_regular_file_is_refused_at_once(tmp_path: Path, case: str) -> None:
    make, reason = BAD_FILES[case]
    path = tmp_path / "rec.jsonl"
    make(path)
    result = cli("eval", "--llm", f"replay:{path}", "--out", str(tmp_path / "o"))
    assert_clean_error(result, f"{path}: cannot read recording {reason}")


@pytest.mark.timeout(HANG_S)
def test_a_results_file_that_is_a_fifo_is_refused_before_a_run_starts(
    tmp_path: Path, small_pattern: Path
) -> None:
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / RunDir.RESULTS)  # size 0: it used to pass for a new run, then block
    args = ["eval", "--method", "classical", "--pattern", str(small_pattern), "--out", str(out)]
    result = cli(*args, "--trials", "1")
    assert_clean_error(result, f"{out / RunDir.RESULTS}: cannot read results file (a FIFO")
    assert not (out / RunDir.MANIFEST).exists()


@pytest.mark.parametrize(
    ("name", "text", "needle"),
    [
        (
            "dup.json",
            '{"name": "a", "name": "b", "brick_size": "full", '
            '"bricks": [{"position": [0, 0, 0.03]}]}',
            "not valid JSON (the key 'name' is given twice)",
        ),
        (
            "dup.yaml",
            "name: a\nbricks: [{position: [0, 0, 0.03]}]\nbrick_size: full\nbricks: []\n",
            "not valid YAML (the key 'bricks' is given twice",
        ),
    ],
)
def test_a_key_given_twice_is_refused_not_overwritten(
    tmp_path: Path, name: str, text: str, needle: str
) -> None:
    path = tmp_path / name
    path.write_text(text)
    assert_clean_error(cli("pattern", str(path)), f"{path}: {needle}")


@pytest.mark.parametrize(
    ("written", "wanted"), [("3.0e0", "3.0e+0"), ("3e-2", "3.0e-2"), ("3E+1", "3.0e+1")]
)
def test_a_number_yaml_reads_as_text_is_refused_saying_how_to_write_it(
    tmp_path: Path, written: str, wanted: str
) -> None:
    """YAML 1.1 wants a point and a signed exponent; the way it is told to write it loads."""
    path = tmp_path / "e.yaml"
    path.write_text(f"name: e\nbrick_size: full\nbricks:\n  - {{position: [0, 0, {written}]}}\n")
    assert_clean_error(
        cli("pattern", str(path)),
        f"{path}: bricks[0].position[2]: Input should be a valid number ('{written}' is read as "
        f"text by YAML: write {wanted})",
    )
    assert isinstance(yaml.safe_load(wanted), float)
