"""The command line as a user runs it: clear one-line errors, real eval runs (in this
process; one test through the real entry point)."""

from __future__ import annotations

import importlib.metadata
import json
import socket
import subprocess
from pathlib import Path

import pytest
from conftest import SMALL_PATTERN, assert_clean_error, cli, cli_process

from actionreasoning.runs.run import RunConfig
from actionreasoning.trial.rules import Method
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.scene_spec import SceneSpec

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "patterns"


BAD_PATTERNS = {
    "not_json.json": ("{ this is not json", "not_json.json"),
    "missing_bricks.json": ('{"name": "x", "brick_size": [0.2, 0.095, 0.06]}', "bricks"),
    "nan.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], '
        '"bricks": [{"position": [0, 0, NaN], "yaw_deg": 0}]}',
        "bricks[0].position",
    ),
    "floating.yaml": (
        "name: f\nbrick_size: [0.2, 0.095, 0.06]\nbricks:\n"
        "  - {position: [0, 0, 0.03], yaw_deg: 0}\n  - {position: [0.25, 0, 0.09], yaw_deg: 0}\n",
        "brick 1",
    ),
    "unreachable.yaml": (
        "name: u\nbrick_size: [0.2, 0.095, 0.06]\norigin: [1.5, 0, 0]\n"
        "bricks:\n  - {position: [0, 0, 0.03], yaw_deg: 0}\n",
        "brick 0",
    ),
    "wrong_type.json": (
        '{"name": "x", "brick_size": 5, "bricks": [{"position": [0, 0, 0.03]}]}',
        "brick_size: Input should be a valid tuple",
    ),
    "unknown_brick.json": (
        '{"name": "x", "brick_size": "big", "bricks": [{"position": [0, 0, 0.03]}]}',
        "brick_size: unknown brick 'big' (the catalogue's: full, half)",
    ),
    "no_name.json": ('{"brick_size": [0.2, 0.095, 0.06], "bricks": []}', "name: Field required"),
    "no_bricks.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], "bricks": []}',
        "bricks: List should have at least 1 item",
    ),
    "negative_size.json": (
        '{"name": "x", "brick_size": [0.2, -0.095, 0.06], "bricks": [{"position": [0, 0, 0.03]}]}',
        "brick_size[1]: Input should be greater than 0",
    ),
    "yaw_text.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], '
        '"bricks": [{"position": [0, 0, 0.03], "yaw_deg": "ninety"}]}',
        "bricks[0].yaw_deg: Input should be a valid number",
    ),
    "infinite.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], "bricks": [{"position": [0, 0, 1e400]}]}',
        "bricks[0].position[2]: Input should be a finite number",
    ),
    "overlapping.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], '
        '"bricks": [{"position": [0, 0, 0.03]}, {"position": [0.05, 0, 0.03]}]}',
        "bricks 0 and 1 overlap",
    ),
    "below_ground.json": (
        '{"name": "x", "brick_size": [0.2, 0.095, 0.06], "bricks": [{"position": [0, 0, -0.02]}]}',
        "brick 0 is below the ground",
    ),
    "broken.yaml": ("name: x\nbrick_size: [0.2, 0.095\n", "not valid YAML"),
    "empty.json": ("", "not valid JSON"),
    "a_list.json": ("[1, 2]", "top level must be a mapping, not list"),
    "binary.json": ("\udcff\udcfe garbage", "cannot read pattern file"),
}


@pytest.mark.parametrize("name", sorted(BAD_PATTERNS))
def test_bad_pattern_files_are_refused_in_one_line(tmp_path: Path, name: str) -> None:
    text, needle = BAD_PATTERNS[name]
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8", "surrogateescape"))  # binary.json: bytes 0xff 0xfe
    result = cli("eval", "--pattern", str(path), "--trials", "1", "--out", str(tmp_path / "o"))
    assert_clean_error(result, name, needle)
    assert not (tmp_path / "o" / "results.jsonl").exists()


@pytest.mark.parametrize("option", ["--pattern", "--physics", "--noise"])
def test_a_file_name_too_long_is_refused_in_one_line(tmp_path: Path, option: str) -> None:
    result = cli("eval", option, "p" * 300 + ".json", "--trials", "1", "--out", str(tmp_path))
    assert_clean_error(result, f"{option.lstrip('-')}: file name too long (305 characters)")


@pytest.mark.parametrize("option", ["--out", "--record"])
def test_an_output_file_name_too_long_is_refused_in_one_line(tmp_path: Path, option: str) -> None:
    paths = {"--out": str(tmp_path / "o"), "--record": str(tmp_path / "r.jsonl")}
    paths[option] = str(tmp_path / ("d" * 300))
    result = cli("eval", "--trials", "1", *(x for pair in paths.items() for x in pair))
    assert_clean_error(result, f"{option}: file name too long")
    assert list(tmp_path.iterdir()) == []


def test_a_demo_out_name_too_long_is_refused_in_one_line(tmp_path: Path) -> None:
    result = cli("demo", "--out", str(tmp_path / ("d" * 300)))
    assert_clean_error(result, "--out: file name too long")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["report", "LONG"], "RUN: file name too long (300 characters)"),
        (["report", "o", "--out", "LONG"], "--out: file name too long (300 characters)"),
        (["pattern", "--wall", "0.83", "--out", "LONG.json"], "--out: file name too long (305"),
        (["eval", "--out", "o", "--llm", "replay:LONG"], "recording: file name too long (300"),
    ],
)
def test_paths_too_long_are_named_by_their_length_not_printed_whole(
    tmp_path: Path, args: list[str], needle: str
) -> None:
    """As eval does for its own options: 300 characters on one error line say nothing."""
    result = cli(*(arg.replace("LONG", "l" * 300) for arg in args), cwd=tmp_path)
    assert_clean_error(result, needle)
    assert "l" * 100 not in result.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["eval", "--out", ""], "--out: empty"),
        (["eval", "--out", "o", "--record", ""], "--record: empty"),
        (["demo", "--out", ""], "--out: empty"),
        (["report", ""], "RUN: empty"),
        (["report", "o", "--out", ""], "--out: empty"),
        (["eval", "--out", "o", "--llm", "replay:"], "needs a --record file after 'replay:'"),
    ],
)
def test_an_empty_path_is_refused_not_taken_as_the_current_directory(
    tmp_path: Path, args: list[str], needle: str
) -> None:
    """``--out ""`` used to run eval in the current directory, and errors named it '.'."""
    result = cli(*args, cwd=tmp_path)
    assert_clean_error(result, needle)
    assert "'.'" not in result.stderr and " . " not in result.stderr
    assert list(tmp_path.iterdir()) == []


def test_transcripts_of_the_classical_method_are_refused(tmp_path: Path) -> None:
    out = tmp_path / "o"
    # Through the real entry point, `python -m actionreasoning`: its exit code and streams.
    result = cli_process("eval", "--method", "classical", "--transcripts", "--out", str(out))
    assert_clean_error(result, "--transcripts", "classical")
    assert not out.exists()


def test_pattern_command_validates_example_files() -> None:
    result = cli("pattern", str(EXAMPLES / "crosswise.json"))
    assert result.returncode == 0, result.stderr
    assert "valid" in result.stdout


@pytest.mark.slow
def test_classical_eval_end_to_end(tmp_path: Path) -> None:
    out = tmp_path / "run"
    result = cli(
        "eval",
        "--method",
        "classical",
        "--pattern",
        "grid",
        "--trials",
        "1",
        "--seed",
        "3",
        "--out",
        str(out),
        "--physics",
        "precise",
    )
    assert result.returncode == 0, result.stderr
    lines = (out / "results.jsonl").read_text().splitlines()
    assert len(lines) == 1
    record = json.loads(lines[0])
    for field in (
        "method",
        "pattern",
        "seed",
        "trial",
        "success",
        "llm",
        "bricks",
        "metrics",
        "failure",
        "llm_usage",
    ):
        assert field in record
    assert record["method"] == "classical" and record["pattern"] == "grid"
    assert (record["physics"], record["noise"]) == ("precise", "none")
    assert len(record["bricks"]) == 6
    brick = record["bricks"][0]
    for field in (
        "id",
        "size",
        "target_position",
        "target_orientation",
        "final_position",
        "final_orientation",
        "center_offset_cm",
        "rotation_error_deg",
        "iou",
    ):
        assert field in brick
    # Under precise physics the grid is built: every brick ends near its target (the script
    # is open loop, so only
    # centimetre accuracy is asserted; the measured figures are in docs/results.md).
    assert all(b["center_offset_cm"] < 2.0 and b["iou"] > 0.8 for b in record["bricks"])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["trials"] == 1
    assert "| classical |" in (out / "summary.md").read_text()
    again = cli("eval", "--trials", "1", "--out", str(out), "--physics", "precise")
    assert_clean_error(again, "holds a different run", "method 'classical' there, 'agents' now")


BAD_FILES = {
    "recording_garbage": ("rec.jsonl", "garbage\n", "rec.jsonl line 1 is not a recording"),
    "recording_headless": ("rec.jsonl", '{"kind": "header"}\n', "is not a recording"),
    "run_json_damaged": ("o/run.json", "not json", "run.json is damaged"),
    "results_damaged": ("o/results.jsonl", "{}\n", "line 1 is not a trial result"),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_broken_recordings_and_run_files_are_refused_in_one_line(tmp_path: Path, case: str) -> None:
    name, text, needle = BAD_FILES[case]
    (tmp_path / "o").mkdir()
    (tmp_path / name).write_text(text)
    if name == "o/results.jsonl":  # the default run's own manifest: only the line is bad
        default = RunConfig(
            method=Method.AGENTS,
            pattern_name="pyramid",
            goal=load_pattern("pyramid", SceneSpec()),
            trials=1,
            seed=0,
            out=tmp_path / "o",
        )
        (tmp_path / "o" / "run.json").write_text(default.manifest().model_dump_json())
    if name == "o/run.json":  # a directory holding results, whose run.json is broken
        (tmp_path / "o" / "results.jsonl").write_text("{}\n")
    llm = ["--llm", f"replay:{tmp_path / name}"] if name == "rec.jsonl" else []
    result = cli("eval", *llm, "--trials", "1", "--out", str(tmp_path / "o"))
    assert_clean_error(result, needle)


def assert_usage_error(result: subprocess.CompletedProcess[str], option: str) -> None:
    """A bad option value: exit 2 and the option named, as for every other bad flag."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    assert option in result.stderr, result.stderr


@pytest.mark.parametrize(
    ("args", "option"),
    [
        (("eval", "--seed", "-1"), "--seed"),
        (("demo", "--seed", "-1"), "--seed"),
        (("prompt", "--agent", "1", "--seed", "-1"), "--seed"),
        (("eval", "--max-trial-s", "inf"), "--max-trial-s"),
        (("eval", "--max-trial-s", "nan"), "--max-trial-s"),
        (("eval", "--llm-timeout", "inf"), "--llm-timeout"),
        (("serve-reference", "--port", "65536"), "--port"),
    ],
)
def test_out_of_range_numbers_are_refused_as_bad_options(
    tmp_path: Path, args: tuple[str, ...], option: str
) -> None:
    has_out = args[0] in ("eval", "demo")
    out = ("--out", str(tmp_path / "o")) if has_out else ()
    result = cli(*args, *out)
    assert_usage_error(result, option)
    assert not (tmp_path / "o").exists()


def test_unwritable_output_directories_are_refused_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    for out in ("/proc/actionreasoning-test", str(tmp_path / "afile" / "sub")):
        result = cli("eval", "--method", "classical", "--trials", "1", "--out", out)
        assert_clean_error(result, out)
    result = cli("report", str(tmp_path), "--out", str(tmp_path / "afile"))
    assert_clean_error(result, str(tmp_path / "afile"))


def test_a_binary_run_file_is_refused_in_one_line(tmp_path: Path) -> None:
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "run.json").write_bytes(bytes(range(256)) * 2)
    (tmp_path / "o" / "results.jsonl").write_text("{}\n")
    result = cli("eval", "--trials", "1", "--out", str(tmp_path / "o"))
    assert_clean_error(result, "run.json is damaged")


@pytest.mark.slow
def test_rich_markup_in_names_and_paths_is_printed_as_text(tmp_path: Path) -> None:
    folder = tmp_path / "p[/]q"  # the slash nests "]q" in "p["
    folder.mkdir(parents=True)
    pattern = folder / "x[bold].json"
    pattern.write_text(json.dumps({**SMALL_PATTERN, "name": "a[/]b"}))
    shown = cli("pattern", str(pattern))
    assert shown.returncode == 0, shown.stderr
    assert "a[/]b" in shown.stdout
    out = tmp_path / "r[/]"
    run = cli(
        "eval", "--method", "classical", "--physics", "precise", "--trials", "1",
        "--pattern", str(pattern), "--out", str(out),
    )  # fmt: skip
    assert run.returncode == 0, run.stderr  # it crashed after writing the results
    assert "classical on" in run.stdout
    report = cli("report", str(out), "--out", str(tmp_path / "rep"))
    assert report.returncode == 0, report.stderr
    assert "x[bold]" in report.stdout  # the column, named after the file


@pytest.mark.slow
def test_a_run_resumes_with_its_pattern_file_spelled_another_way(
    tmp_path: Path, small_pattern: Path
) -> None:
    common = ("eval", "--method", "classical", "--physics", "precise", "--out", "r")
    first = cli(*common, "--trials", "1", "--pattern", small_pattern.name, cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    again = cli(*common, "--trials", "2", "--pattern", f"./{small_pattern.name}", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    assert "resuming: 1 of 2" in again.stdout


def test_tools_are_refused_with_the_classical_script(tmp_path: Path) -> None:
    """It asks no agent, so a tier would only split identical report rows and block resumes."""
    result = cli("eval", "--method", "classical", "--tools", "none", "--out", str(tmp_path / "o"))
    assert_clean_error(result, "--method classical gives no agent tools; drop --tools")


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (
            ("eval", "--method", "classical", "--observe", "both"),
            "--method classical asks no agent; drop --observe both",
        ),
        (
            ("eval", "--method", "single-agent", "--observe", "image"),
            "--method single-agent names its brick by id: observe state or both, not image",
        ),
        (
            ("prompt", "--agent", "0", "--observe", "image"),
            "--method single-agent names its brick by id: observe state or both, not image",
        ),
    ],
    ids=["classical", "single agent", "single agent's prompt"],
)
def test_an_observation_the_method_cannot_run_under_is_refused(
    tmp_path: Path, args: tuple[str, ...], message: str
) -> None:
    """The classical script asks no agent; the single agent names its brick by id, which
    the image tier shows none of (its prompt was a traceback)."""
    out = ("--out", str(tmp_path / "o")) if args[0] == "eval" else ()
    assert_clean_error(cli(*args, *out), message)
    assert not (tmp_path / "o").exists()


@pytest.mark.slow  # one classical trial
def test_answer_errors_minus_zero_is_the_run_without_them(tmp_path: Path) -> None:
    """-0 is stored as 0: the same configuration, so a resume without the flag is the run."""
    pattern = tmp_path / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    out = tmp_path / "o"
    args = ("eval", "--method", "classical", "--pattern", str(pattern), "--trials", "1")
    first = cli(*args, "--answer-errors", "-0", "--out", str(out))
    assert first.returncode == 0, first.stderr
    run = json.loads((out / "run.json").read_text())
    assert json.dumps(run["config"]["answer_errors"]["rate"]) == "0.0"
    again = cli(*args, "--out", str(out))
    assert again.returncode == 0, again.stderr
    assert len((out / "results.jsonl").read_text().splitlines()) == 1


@pytest.mark.parametrize(
    "args",
    [
        ("pattern", "{p}"),
        ("tolerances", "--pattern", "{p}"),
        ("eval", "--pattern", "{p}", "--trials", "1", "--out", "{o}"),
        ("eval", "--method", "single-agent", "--pattern", "{p}", "--trials", "1", "--out", "{o}"),
    ],
    ids=["pattern", "tolerances", "eval", "single-agent"],
)
def test_a_pattern_too_tight_for_the_gates_is_refused_before_any_trial(
    tmp_path: Path, args: tuple[str, ...]
) -> None:
    """Not called valid, and no trial run against a tolerance no measurement can meet."""
    from test_gates import TIGHT

    pattern, out = tmp_path / "tight.json", tmp_path / "o"
    pattern.write_text(json.dumps(TIGHT))
    result = cli(*(a.format(p=pattern, o=out) for a in args))
    assert_clean_error(result, "the joint between targets 0 and 1 is 0.0 mm", "wider than 4.1 mm")
    assert not out.exists()


def test_a_tight_pattern_still_runs_the_classical_script(tmp_path: Path) -> None:
    """It asks no gate: only the agents need the joint."""
    from test_gates import TIGHT

    pattern = tmp_path / "tight.json"
    pattern.write_text(json.dumps(TIGHT))
    args = ("eval", "--method", "classical", "--pattern", str(pattern), "--trials", "1")
    result = cli(*args, "--out", str(tmp_path / "o"))
    assert result.returncode == 0, result.stderr


def test_a_run_that_fails_to_start_leaves_no_out_directory(tmp_path: Path) -> None:
    """Nothing listens on the port: the structured-output probe fails before any trial, and
    the directory the run made for itself goes with it (it held only an empty run.lock)."""
    out = tmp_path / "o"
    with socket.socket() as free:  # a loopback port nobody listens on
        free.bind(("127.0.0.1", 0))
        port = free.getsockname()[1]
    dead = f"http://127.0.0.1:{port}/v1"
    result = cli("eval", "--llm", "openai:m", "--base-url", dead, "--llm-retries", "0",
                 "--trials", "1", "--out", str(out))  # fmt: skip
    assert_clean_error(result, "llm_unreachable: cannot connect to")
    assert not out.exists()


def test_version_is_the_installed_distributions() -> None:
    shown = cli("--version")
    assert shown.returncode == 0, shown.stderr
    assert shown.stdout == f"actionreasoning {importlib.metadata.version('actionreasoning')}\n"
