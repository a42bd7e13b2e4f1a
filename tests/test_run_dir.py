"""The output directory of a run on its own (no simulation): what resume reads and refuses."""

from __future__ import annotations

import hashlib
import json
from io import StringIO
from pathlib import Path
from typing import Any

import pytest
from rich.console import Console

from actionreasoning.agents.verification import Verification
from actionreasoning.control.limits import ControllerLimits
from actionreasoning.errors import ConfigError
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.records import Failure
from actionreasoning.report.runs import read_run
from actionreasoning.runs.progress import ConsoleProgress
from actionreasoning.runs.run_dir import (
    MAX_LINE_BYTES,
    RunManifest,
    append_result,
    open_run,
    read_results,
)
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.provenance import Provenance
from actionreasoning.trial.results import PlacementMetrics, TrialResult
from actionreasoning.trial.rules import trial_seed
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.tolerances import Tolerances


def manifest(seed: int = 0, **config: Any) -> RunManifest:
    """run.json of an agents run on the pyramid under ``config`` (else the defaults)."""
    return RunManifest.sealed("agents", "pyramid", "0" * 64, seed, TrialConfig(**config))


MANIFEST = manifest()


def result(trial: int, success: bool = True) -> TrialResult:
    return TrialResult(
        method="agents", pattern="pyramid", tools="check", seed=0, trial=trial,
        trial_seed=trial_seed(0, trial), success=success,
        llm="builtin", bricks=(), bricks_placed=0,
        metrics=PlacementMetrics(
            center_offset_cm=0.01, rotation_error_deg=0.02, symmetric_rotation_error_deg=0.02,
            iou=0.99,
        ),
        failure=None if success else Failure(reason="misplaced", detail="brick 3"), sim_steps=10,
    )  # fmt: skip


def write_run(out: Path, trials: int) -> None:
    assert open_run(out, MANIFEST) == []
    with (out / "results.jsonl").open("ab", buffering=0) as sink:
        for trial in range(trials):
            append_result(sink, result(trial).model_copy(update={"physics": "paper"}))


def test_a_partial_last_line_is_cut_off_and_whole_lines_kept(tmp_path: Path) -> None:
    write_run(tmp_path, 2)
    path = tmp_path / "results.jsonl"
    whole = path.read_bytes()
    path.write_bytes(whole + result(2).model_dump_json()[:57].encode())  # killed mid-write
    assert [r.trial for r in read_results(path)] == [0, 1]
    assert path.read_bytes() != whole  # reading alone repairs nothing
    assert [r.trial for r in open_run(tmp_path, MANIFEST)] == [0, 1]
    assert path.read_bytes() == whole


def test_a_whole_last_line_without_its_newline_is_kept_and_the_newline_added(
    tmp_path: Path,
) -> None:
    write_run(tmp_path, 2)
    path = tmp_path / "results.jsonl"
    whole = path.read_bytes()
    path.write_bytes(whole[:-1])
    assert [r.trial for r in read_results(path)] == [0, 1]
    assert path.read_bytes() == whole[:-1]  # reading alone repairs nothing
    assert [r.trial for r in open_run(tmp_path, MANIFEST)] == [0, 1]
    assert path.read_bytes() == whole


def test_a_different_run_is_refused_naming_what_differs(tmp_path: Path) -> None:
    write_run(tmp_path, 1)
    other = manifest(seed=4, llm=LLMConfig(spec="openai:m"))
    with pytest.raises(ConfigError, match=r"seed 0 there, 4 now, llm\.spec 'builtin' there"):
        open_run(tmp_path, other)


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        ("{not json}\n", r"line 2 is not a trial result"),
        (None, r"line 2 repeats trial 0"),
        (result(0).model_copy(update={"trial": -1}), r"line 2: trial -1 of seed 0 is not a trial"),
        (result(1).model_copy(update={"trial": 7}), r"line 2: trial 7 of seed 0 has trial_seed"),
        (
            result(1).model_copy(update={"seed": 7, "trial_seed": trial_seed(7, 1)}),
            r"line 2 is a trial of seed 7",
        ),
    ],
)
def test_damaged_results_are_refused_with_the_line(
    tmp_path: Path, damage: str | TrialResult | None, message: str
) -> None:
    write_run(tmp_path, 1)
    path = tmp_path / "results.jsonl"
    first = path.read_text()
    if isinstance(damage, TrialResult):
        damage = damage.model_dump_json() + "\n"
    path.write_text(first + (damage or first))
    with pytest.raises(ConfigError, match=message):
        open_run(tmp_path, MANIFEST)


def test_results_without_a_manifest_are_not_mixed_into(tmp_path: Path) -> None:
    (tmp_path / "results.jsonl").write_text(result(0).model_dump_json() + "\n")
    with pytest.raises(ConfigError, match=r"run\.json does not"):
        open_run(tmp_path, MANIFEST)


def test_the_progress_bar_counts_resumed_trials_and_successes() -> None:
    buffer = StringIO()
    console = Console(file=buffer, force_terminal=True, width=120)
    with ConsoleProgress(console, "agents / pyramid") as progress:
        progress.started(4, [result(0)])
        progress.finished(result(1, success=False))
        progress.finished(result(2))
    text = buffer.getvalue()
    assert "resuming: 1 of 4 trials already in results.jsonl (1 ok)" in text
    assert "trial 1: FAILED (misplaced: brick 3)" in text
    assert "3/4" in text and "2 ok" in text


def test_plain_lines_when_not_a_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    console = Console(file=StringIO(), force_terminal=False)
    with ConsoleProgress(console, "x") as progress:
        progress.started(2, [])
        progress.finished(result(0))
    assert capsys.readouterr().out.splitlines() == [
        "[1/2, 1 ok] trial 0: ok; mean 0.010 cm, 0.020 deg, IoU 0.990"
    ]


def test_a_resume_under_other_conditions_is_refused_naming_the_field(tmp_path: Path) -> None:
    write_run(tmp_path, 1)
    with pytest.raises(ConfigError, match=r"physics\.name 'paper' there, 'precise' now"):
        open_run(tmp_path, manifest(physics=PRECISE))
    with pytest.raises(ConfigError, match=r"noise\.perception\.position_std_m 0\.0 there"):
        open_run(tmp_path, manifest(noise=NOISE["medium"]))
    assert open_run(tmp_path, MANIFEST) == [result(0).model_copy(update={"physics": "paper"})]


def test_a_resume_at_another_rung_of_verification_is_refused(tmp_path: Path) -> None:
    """The rung is part of run.json (at the method's own, left out: runs from before rungs
    resume)."""
    assert "verify" not in MANIFEST.model_dump_json()
    open_run(tmp_path, MANIFEST)
    (tmp_path / "results.jsonl").write_text(result(0).model_dump_json() + "\n")
    with pytest.raises(ConfigError, match=r"verify None there, 'gates' now"):
        open_run(tmp_path, manifest(verify=Verification.GATES))


def test_an_interrupt_while_a_whole_line_is_synced_keeps_the_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C can land in the fsync after a trial's line is written whole (the Ctrl-C test in
    test_eval_scale.py saw it lost once); no signal can be timed into that call, so the
    interrupt is raised from it here."""
    write_run(tmp_path, 1)
    path = tmp_path / "results.jsonl"

    def interrupted(descriptor: int) -> None:
        raise KeyboardInterrupt

    with path.open("ab", buffering=0) as sink:
        monkeypatch.setattr("os.fsync", interrupted)
        with pytest.raises(KeyboardInterrupt):
            append_result(sink, result(1))
    monkeypatch.undo()
    assert [r.trial for r in read_results(path)] == [0, 1]


def test_a_changed_setting_is_refused_naming_each_field_with_both_values(tmp_path: Path) -> None:
    write_run(tmp_path, 1)
    changed = manifest(
        tolerances=Tolerances(c_min_m=0.025), controller=ControllerLimits(max_joint_speed_radps=2.0)
    )
    with pytest.raises(ConfigError) as refused:
        open_run(tmp_path, changed)
    message = str(refused.value)
    assert f"tolerances.c_min_m {Tolerances().c_min_m} there, 0.025 now" in message
    assert "controller.max_joint_speed_radps 2.5 there, 2.0 now" in message
    assert "choose another --out" in message
    assert message.count(" there, ") == 2  # nothing else is named
    assert [r.trial for r in open_run(tmp_path, manifest())] == [0]


def test_a_hand_edited_config_is_refused(tmp_path: Path) -> None:
    write_run(tmp_path, 1)
    stored = json.loads((tmp_path / "run.json").read_text())
    stored["config"]["tolerances"]["c_min_m"] = 0.025
    (tmp_path / "run.json").write_text(json.dumps(stored))
    with pytest.raises(ConfigError, match=r"config_sha256 is not the hash of config"):
        open_run(tmp_path, MANIFEST)


#: run.json as versions before the trial configuration was recorded wrote it.
EARLIER_MANIFEST = {
    "method": "agents",
    "pattern": "pyramid",
    "pattern_sha256": "0" * 64,
    "seed": 0,
    "llm": "builtin",
    "llm_limits": {"tool_turns": 2, "repairs": 2, "fallback": False},
    "success_rule": "every brick within 2 cm and 5 deg",
    "budget": {"max_steps": 400000, "max_wall_s": 3600.0},
    "physics": PRECISE.model_dump(mode="json"),
    "noise": NOISE["none"].model_dump(mode="json"),
}


def test_a_run_of_an_earlier_version_is_reported_but_not_resumed(tmp_path: Path) -> None:
    """Its lines lack the provenance fields and its run.json the trial configuration: a
    report reads both, a resume is refused, and nothing is changed."""
    (tmp_path / "run.json").write_text(json.dumps(EARLIER_MANIFEST))
    provenance = set(Provenance.model_fields)
    lines = [
        json.dumps(result(trial).model_dump(mode="json", exclude={*provenance, "tools"})) + "\n"
        for trial in range(2)
    ]
    assert all('"schema_version"' not in line for line in lines)
    (tmp_path / "results.jsonl").write_text("".join(lines))
    with pytest.raises(ConfigError, match=r"run\.json was written by an earlier version.*--out"):
        open_run(tmp_path, MANIFEST)
    assert (tmp_path / "results.jsonl").read_text() == "".join(lines)
    run = read_run(tmp_path)
    assert [(r.trial, r.schema_version, r.git_revision) for r in run.results] == [
        (0, None, None),
        (1, None, None),
    ]
    conditions = run.conditions()
    assert conditions["budget.max_steps"] == 400000 and conditions["llm.spec"] == "builtin"
    assert conditions["physics.name"] == "precise" and "tolerances.c_min_m" not in conditions


def test_a_run_whose_configuration_this_version_reads_no_more_is_reported_not_resumed(
    tmp_path: Path,
) -> None:
    """A run.json of an earlier version with a threshold since renamed (sigma_3's
    grip_safety_factor, now grip_load_factor): a report reads it as it was recorded, a
    resume is refused, and nothing is changed."""
    write_run(tmp_path, 2)
    stored = json.loads((tmp_path / "run.json").read_text())
    tolerances = stored["config"]["tolerances"]
    tolerances["grip_safety_factor"] = 2.0
    del tolerances["grip_load_factor"]
    recorded = json.dumps(stored["config"], sort_keys=True, separators=(",", ":"))
    stored["config_sha256"] = hashlib.sha256(recorded.encode()).hexdigest()
    (tmp_path / "run.json").write_text(json.dumps(stored))
    lines = (tmp_path / "results.jsonl").read_text()
    with pytest.raises(ConfigError, match=r"reads no more, so it cannot be resumed"):
        open_run(tmp_path, MANIFEST)
    assert (tmp_path / "results.jsonl").read_text() == lines
    run = read_run(tmp_path)
    assert [r.trial for r in run.results] == [0, 1]
    conditions = run.conditions()
    assert conditions["tolerances.grip_safety_factor"] == 2.0
    assert conditions["physics.name"] == "paper"
    # Edited by hand, it is damaged, not an earlier version.
    stored["config"]["tolerances"]["c_min_m"] = 0.5
    (tmp_path / "run.json").write_text(json.dumps(stored))
    with pytest.raises(ConfigError, match=r"damaged or from an earlier version"):
        read_run(tmp_path)


def test_a_file_of_nul_bytes_is_not_a_results_file_and_is_left_as_it_is(tmp_path: Path) -> None:
    """Not "empty" (its one line taken for a line cut short), and a resume does not cut it
    away: it is no results file at all."""
    assert open_run(tmp_path, MANIFEST) == []
    path = tmp_path / "results.jsonl"
    path.write_bytes(b"\0" * 5000)
    for read in (lambda: read_run(tmp_path), lambda: open_run(tmp_path, MANIFEST)):
        with pytest.raises(
            ConfigError, match=r"results\.jsonl is not a results file \(it holds NUL"
        ):
            read()
    assert path.read_bytes() == b"\0" * 5000


@pytest.mark.parametrize("ending", [b"", b"\n"])
def test_a_line_longer_than_any_result_is_refused_with_its_number(
    tmp_path: Path, ending: bytes
) -> None:
    """Read in pieces and refused once too long, never read whole; a resume cuts nothing."""
    write_run(tmp_path, 2)
    path = tmp_path / "results.jsonl"
    whole = path.read_bytes()
    path.write_bytes(whole + b"x" * (MAX_LINE_BYTES + 1) + ending + whole)
    size = path.stat().st_size
    for read in (lambda: read_results(path, repair=True), lambda: open_run(tmp_path, MANIFEST)):
        with pytest.raises(ConfigError, match=r"line 3 is longer than 64 MiB: not a trial result"):
            read()
    assert path.stat().st_size == size
    # At the limit, it is read as a line: refused as what it is, not for its length.
    path.write_bytes(whole + b"x" * MAX_LINE_BYTES + b"\n")
    with pytest.raises(ConfigError, match=r"line 3 is not a trial result \(Invalid JSON"):
        read_results(path)


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("physics", "precise"),
        ("noise", "high"),
        ("tools", "none"),
        ("llm", "builtin"),
        ("verify", "full"),
        ("observe", "both"),
    ],
)
def test_a_line_of_another_condition_is_refused_by_a_resume_and_by_report(
    tmp_path: Path, field: str, value: Any
) -> None:
    """Copied in or written by hand: a resume pooled it and exited 0 where `report` refused
    it. Both now refuse it with the same line, naming the line and the field."""
    from conftest import SMALL_PATTERN, cli

    pattern = tmp_path / "small.json"
    pattern.write_text(json.dumps(SMALL_PATTERN))
    out = tmp_path / "o"
    args = ("eval", "--method", "classical", "--pattern", str(pattern), "--seed", "0")
    assert cli(*args, "--trials", "1", "--out", str(out)).returncode == 0
    results = out / "results.jsonl"
    line = json.loads(results.read_text()) | {field: value}
    results.write_text(json.dumps(line) + "\n")
    resumed = cli(*args, "--trials", "2", "--out", str(out))
    assert resumed.returncode == 2 and "Traceback" not in resumed.stderr
    assert f"{results} line 1 is a trial of {field} " in " ".join(resumed.stderr.split())
    assert len(results.read_text().splitlines()) == 1  # nothing ran, nothing was pooled
    with pytest.raises(ConfigError, match=f"line 1 is a trial of {field} "):
        read_run(out)
