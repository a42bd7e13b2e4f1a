"""An evaluation run: trials of one method on one pattern, written to an output directory.

results.jsonl gets one line per finished trial, flushed as it finishes; summary.json and
summary.md are written at the end; with transcripts, transcripts/trial_NNN.jsonl holds every
agent call of trial NNN.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from actionreasoning.errors import ConfigError
from actionreasoning.eval.results import TrialResult
from actionreasoning.eval.snapshots import SnapshotRecorder
from actionreasoning.eval.summary import RunSummary, summarize, summary_markdown
from actionreasoning.eval.trial import Method, SuccessRule, TrialRun, TrialSpec, run_trial
from actionreasoning.reasoners.factory import LLMConfig, prepare
from actionreasoning.world.models import GoalPattern

RESULTS_FILE = "results.jsonl"


@dataclass(frozen=True)
class RunConfig:
    """The options of one eval run."""

    method: Method
    pattern_name: str
    goal: GoalPattern
    trials: int
    seed: int
    out: Path
    llm: LLMConfig = LLMConfig()
    snapshots: bool = False
    transcripts: bool = False


def prepare_out_dir(out: Path) -> Path:
    """Create ``out``; refuse one that already holds results, so runs never mix."""
    results = out / RESULTS_FILE
    if results.exists() and results.stat().st_size > 0:
        raise ConfigError(f"{results} already exists: choose another --out or remove it")
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    return results


def write_transcript(path: Path, run: TrialRun) -> None:
    """One JSON line per agent call of the trial."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("".join(call.model_dump_json() + "\n" for call in run.transcript))


def run_eval(
    config: RunConfig, on_trial: Callable[[TrialResult], None] | None = None
) -> RunSummary:
    """Run every trial, append each result as it finishes, then write the summaries."""
    results_path = prepare_out_dir(config.out)
    llm = prepare(config.llm) if config.method is not Method.CLASSICAL else config.llm
    rule = SuccessRule()
    started = time.perf_counter()
    results: list[TrialResult] = []
    with results_path.open("a", encoding="utf-8") as sink:
        for trial in range(config.trials):
            spec = TrialSpec(
                method=config.method,
                pattern_name=config.pattern_name,
                goal=config.goal,
                run_seed=config.seed,
                trial=trial,
                llm=llm,
            )
            hook = (
                SnapshotRecorder(config.out / "snapshots" / f"trial_{trial:03d}")
                if config.snapshots
                else None
            )
            run = run_trial(spec, rule, hook)
            result = run.result
            if config.transcripts:
                write_transcript(config.out / "transcripts" / f"trial_{trial:03d}.jsonl", run)
            sink.write(result.model_dump_json() + "\n")
            sink.flush()
            results.append(result)
            if on_trial is not None:
                on_trial(result)
    mode = None if llm.mode is None else str(llm.mode)
    summary = summarize(results, time.perf_counter() - started, rule, llm_mode=mode)
    (config.out / "summary.json").write_text(summary.model_dump_json(indent=2) + "\n")
    (config.out / "summary.md").write_text(summary_markdown(summary))
    return summary
