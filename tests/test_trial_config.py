"""One trial configuration, recorded as run: a real run's run.json holds all of it with its
hash, a resume under any other value is refused naming the field, each part reaches the
code that uses it, and every line and summary names the code that wrote it."""

from __future__ import annotations

import json
import shutil
import subprocess
from importlib import metadata
from pathlib import Path

import pytest
from jsonschema import Draft202012Validator
from typer.testing import CliRunner

import actionreasoning
from actionreasoning.cli import app
from actionreasoning.control.safety import SafetyLimits
from actionreasoning.errors import ConfigError
from actionreasoning.runs.run import RunConfig, run_eval
from actionreasoning.runs.run_dir import config_digest
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.provenance import SCHEMA_VERSION, Provenance, git_revision
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec, run_trial
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.success import SuccessRule
from actionreasoning.world.tolerances import Tolerances

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}
#: Where the classical script builds the one brick (no slip under precise physics).
CONFIG = TrialConfig(physics=PRECISE)


@pytest.fixture(scope="module")
def pattern(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("pattern") / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


def run_config(pattern: Path, out: Path, config: TrialConfig = CONFIG) -> RunConfig:
    return RunConfig(
        method=Method.CLASSICAL,
        pattern_name=str(pattern),
        goal=load_pattern(pattern, SceneSpec()),
        trials=1,
        seed=0,
        out=out,
        config=config,
    )


@pytest.fixture(scope="module")
def finished(pattern: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished classical run of one trial."""
    out = tmp_path_factory.mktemp("runs") / "finished"
    run_eval(run_config(pattern, out))
    return out


def spec(pattern: Path, config: TrialConfig) -> TrialSpec:
    goal = load_pattern(pattern, SceneSpec())
    return TrialSpec(Method.CLASSICAL, str(pattern), goal, run_seed=0, trial=0, config=config)


def test_run_json_records_every_value_of_the_config_and_its_hash(finished: Path) -> None:
    stored = json.loads((finished / "run.json").read_text())
    assert list(stored) == [
        "method", "pattern", "pattern_sha256", "supply", "seed", "config", "config_sha256",
    ]  # fmt: skip
    assert stored["supply"] == "scattered"
    classical = CONFIG.model_copy(update={"llm": None})
    assert stored["config"] == classical.model_dump(mode="json")
    assert stored["config"]["tolerances"]["c_min_m"] == Tolerances().c_min_m
    assert stored["config"]["llm"] is None  # the classical script asks no reasoner
    assert stored["config_sha256"] == config_digest(classical)


def test_a_changed_default_is_refused_and_the_same_defaults_resume(
    pattern: Path, finished: Path, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    shutil.copytree(finished, out)
    lines = (out / "results.jsonl").read_bytes()
    changed = CONFIG.model_copy(update={"tolerances": Tolerances(c_min_m=0.025)})
    with pytest.raises(ConfigError) as refused:
        run_eval(run_config(pattern, out, changed))
    message = str(refused.value)
    assert f"tolerances.c_min_m {Tolerances().c_min_m} there, 0.025 now" in message
    assert "choose another --out" in message
    assert (out / "results.jsonl").read_bytes() == lines
    summary = run_eval(run_config(pattern, out))
    assert summary.resumed_trials == 1 and summary.trials == 1  # no trial ran again
    assert (out / "results.jsonl").read_bytes() == lines


@pytest.mark.slow  # three whole trials
def test_the_safety_limits_and_success_rule_of_the_config_are_the_ones_applied(
    pattern: Path,
) -> None:
    assert run_trial(spec(pattern, CONFIG)).result.success
    slow = CONFIG.model_copy(update={"safety": SafetyLimits(max_tcp_speed_mps=0.5)})
    failure = run_trial(spec(pattern, slow)).result.failure
    assert failure is not None and failure.reason == "safety_limit", failure
    strict = CONFIG.model_copy(update={"success_rule": SuccessRule(max_center_offset_cm=1e-6)})
    failure = run_trial(spec(pattern, strict)).result.failure
    assert failure is not None and failure.reason == "misplaced", failure


def test_lines_and_summaries_name_the_code_that_wrote_them(pattern: Path, finished: Path) -> None:
    line = (finished / "results.jsonl").read_text().splitlines()[0]
    record, summary = json.loads(line), json.loads((finished / "summary.json").read_text())
    package = Path(actionreasoning.__file__).parent
    stamp = Provenance(
        schema_version=SCHEMA_VERSION,
        package_version=metadata.version("actionreasoning"),
        git_revision=git_revision(package),
        pybullet_version=metadata.version("pybullet"),
    )
    for written in (record, summary):
        assert {name: written[name] for name in Provenance.model_fields} == stamp.model_dump()
    checkout = Path(__file__).parent.parent
    if shutil.which("git") and package.is_relative_to(checkout / "src"):
        # A checkout's HEAD; none for a copy of the tree that is no git checkout.
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=checkout, capture_output=True)
        expected = head.stdout.decode().strip() if head.returncode == 0 else None
        assert stamp.git_revision == expected
    # Byte for byte, the line is those fields, then the trial's own line as run here.
    own = run_trial(spec(pattern, CONFIG)).result
    own_line = own.model_dump_json(exclude=set(Provenance.model_fields))
    assert line == stamp.model_dump_json()[:-1] + "," + own_line[1:]


def git(where: Path, *args: str) -> str:
    done = subprocess.run(["git", *args], cwd=where, capture_output=True, text=True, check=True)
    return done.stdout.strip()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_the_git_revision_is_that_of_a_checkout_tracking_the_package(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    repo = tmp_path / "repo"
    (repo / "pkg").mkdir(parents=True)
    (repo / "pkg" / "__init__.py").write_text("")
    (repo / "venv" / "pkg").mkdir(parents=True)  # an installed copy, untracked
    (repo / "venv" / "pkg" / "__init__.py").write_text("")
    git(repo, "init", "-q")
    git(repo, "add", "pkg")
    git(repo, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "x")
    assert git_revision(repo / "pkg") == git(repo, "rev-parse", "HEAD")
    assert git_revision(repo / "venv" / "pkg") is None
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path))
    assert git_revision(outside) is None
    monkeypatch.setenv("PATH", str(tmp_path / "no-git-here"))
    assert git_revision(repo / "pkg") is None


@pytest.mark.parametrize(
    ("records", "files"),
    [("results", "results.jsonl"), ("summary", "summary.json"), ("config", "run.json")],
)
def test_the_schema_command_prints_a_schema_the_written_files_meet(
    finished: Path, records: str, files: str
) -> None:
    printed = CliRunner().invoke(app, ["schema", records])
    assert printed.exit_code == 0, printed.output
    validator = Draft202012Validator(json.loads(printed.output))
    text = (finished / files).read_text()
    if records == "results":
        documents = [json.loads(line) for line in text.splitlines()]
    else:
        stored = json.loads(text)
        documents = [stored["config"] if records == "config" else stored]
    for document in documents:
        validator.validate(document)
    if records == "results":
        assert set(Provenance.model_fields) <= set(validator.schema["properties"])


def test_the_schema_command_names_what_it_prints() -> None:
    refused = CliRunner().invoke(app, ["schema", "nonsense"])
    assert refused.exit_code == 2 and "results" in refused.output
    helped = CliRunner().invoke(app, ["schema", "--help"])
    assert "results.jsonl" in helped.output and "summary.json" in helped.output
