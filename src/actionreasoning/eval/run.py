"""An evaluation run: trials of one method on one pattern, written to an output directory.

results.jsonl gets one line per finished trial, as it finishes; running the same command
again skips the trials already there (run_dir.py). Trials run one after another, in worker
processes or on a Ray cluster (jobs.py); only this process writes files, and only while it
holds the directory's lock (run_lock.py). With transcripts, transcripts/trial_NNN.jsonl
holds every agent call of trial NNN; with snapshots, snapshots/trial_NNN/ its pictures,
written after its result line, so a disk that fills up costs pictures, never a result.
summary.json and summary.md are written at the end. A write that fails ends the run with
a :class:`StorageError` saying what is kept.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Protocol

from actionreasoning.errors import ConfigError
from actionreasoning.eval.jobs import (
    TrialJob,
    TrialOutput,
    run_in_processes,
    run_on_ray,
    run_serial,
)
from actionreasoning.eval.results import TrialResult
from actionreasoning.eval.rules import Method, SuccessRule
from actionreasoning.eval.run_dir import (
    RESULTS_FILE,
    RunManifest,
    append_result,
    digest,
    open_run,
    write_error,
    write_file,
)
from actionreasoning.eval.run_lock import run_lock
from actionreasoning.eval.summary import RunSummary, describe_rule, summarize, summary_markdown
from actionreasoning.eval.trial import TrialSpec
from actionreasoning.reasoners.factory import LLMConfig, prepare
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.noise import LEVELS, NoiseLevel
from actionreasoning.world.physics import PAPER, PhysicsProfile


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
    workers: int = 1
    ray: str | None = None
    rule: SuccessRule = SuccessRule()
    budget: TrialBudget = TrialBudget()
    physics: PhysicsProfile = PAPER
    noise: NoiseLevel = LEVELS["none"]

    def manifest(self) -> RunManifest:
        """What a resumed run must share with this one."""
        reasoned = self.method is not Method.CLASSICAL
        return RunManifest(
            method=str(self.method),
            pattern=self.pattern_name,
            pattern_sha256=digest(self.goal.model_dump_json()),
            seed=self.seed,
            llm=self.llm.spec if reasoned else "none",
            llm_limits={**asdict(self.llm.limits), "fallback": self.llm.fallback}
            if reasoned
            else {},
            success_rule=describe_rule(self.rule),
            budget=asdict(self.budget),
            physics=self.physics,
            noise=self.noise,
        )


class RunObserver(Protocol):
    """Told what a run resumes and of every trial as it finishes (progress display)."""

    def started(self, total: int, finished: list[TrialResult]) -> None: ...

    def finished(self, result: TrialResult) -> None: ...


def check_engine(config: RunConfig) -> None:
    """Refuse engine options that cannot work together."""
    if config.workers > 1 and config.ray:
        raise ConfigError("--workers and --ray exclude each other: Ray places the trials itself")
    if config.llm.record and (config.workers > 1 or config.ray):
        raise ConfigError(
            "--record writes one file from one process: use it without --workers/--ray"
        )


def run_eval(config: RunConfig, observer: RunObserver | None = None) -> RunSummary:
    """Run the trials not yet in ``config.out``, append each as it finishes, then summarize;
    all while holding the directory, which another run may not write meanwhile."""
    check_engine(config)
    with run_lock(config.out):
        return _run_locked(config, observer)


def _run_locked(config: RunConfig, observer: RunObserver | None) -> RunSummary:
    llm = prepare(config.llm) if config.method is not Method.CLASSICAL else config.llm
    finished = open_run(config.out, config.manifest())
    results = [r for r in finished if r.trial < config.trials]
    resumed = len(results)
    if observer is not None:
        observer.started(config.trials, list(results))
    jobs = _jobs(config, llm, {r.trial for r in results})
    started = time.perf_counter()
    path = config.out / RESULTS_FILE
    with path.open("ab", buffering=0) as sink:
        for output in _engine(config, jobs, config.trials - resumed):
            try:
                append_result(sink, output.result)
            except OSError as error:
                raise write_error(path, error, _kept(len(results))) from error
            results.append(output.result)
            _write_outputs(config, output, _kept(len(results)))
            if observer is not None:
                observer.finished(output.result)
    mode = None if llm.mode is None else str(llm.mode)
    summary = summarize(
        sorted(results, key=lambda r: r.trial),
        time.perf_counter() - started,
        config.rule,
        llm_mode=mode,
        resumed_trials=resumed,
        physics=config.physics,
        noise=config.noise,
    )
    kept = _kept(len(results))
    write_file(
        config.out / "summary.json", (summary.model_dump_json(indent=2) + "\n").encode(), kept
    )
    write_file(config.out / "summary.md", summary_markdown(summary).encode(), kept)
    return summary


def _kept(finished: int) -> str:
    return f"{finished} finished trial{'s' if finished != 1 else ''} kept in {RESULTS_FILE}"


def _jobs(config: RunConfig, llm: LLMConfig, done: set[int]) -> Iterator[TrialJob]:
    """The trials not in ``done``, in order, each made when an engine asks for it: a run of
    any length starts at once and holds only the jobs in flight."""
    for trial in range(config.trials):
        if trial in done:
            continue
        spec = TrialSpec(
            method=config.method,
            pattern_name=config.pattern_name,
            goal=config.goal,
            run_seed=config.seed,
            trial=trial,
            llm=llm,
            budget=config.budget,
            physics=config.physics,
            noise=config.noise,
        )
        yield TrialJob(
            spec=spec,
            rule=config.rule,
            snapshots=config.snapshots,
            transcripts=config.transcripts,
        )


def _engine(config: RunConfig, jobs: Iterator[TrialJob], count: int) -> Iterator[TrialOutput]:
    """The engine for ``count`` jobs."""
    if config.ray:
        return run_on_ray(jobs, config.ray)
    if config.workers > 1 and count > 1:
        return run_in_processes(jobs, min(config.workers, count))
    return run_serial(jobs)


def _write_outputs(config: RunConfig, output: TrialOutput, kept: str) -> None:
    """A trial's transcript and pictures, written after its result line."""
    name = f"trial_{output.result.trial:03d}"
    files: dict[Path, bytes] = {}
    if config.transcripts:
        files[Path("transcripts") / f"{name}.jsonl"] = output.transcript.encode()
    if config.snapshots:
        files |= {Path("snapshots") / name / path: data for path, data in output.pictures.items()}
    incomplete = f"not all of trial {output.result.trial}'s pictures and transcript are written"
    for path, data in files.items():
        write_file(config.out / path, data, f"{incomplete}; {kept}")
