"""An evaluation run: trials of one method on one pattern, written to an output directory
(laid out as layout.py says).

results.jsonl gets one line per finished trial, as it finishes; running the same command
again skips the trials already there (run_dir.py). Trials run one after another, in worker
processes or on a Ray cluster (jobs.py); only this process writes files, and only while it
holds the directory's lock (run_lock.py). It stamps every line with the code that wrote it
(provenance.py). With transcripts, every agent call of a trial is kept; with snapshots, its
pictures; with rerun, its Rerun recording: all written after its result line, so a disk
that fills up costs pictures, never a result. summary.json and summary.md are written at
the end. A write that fails ends the run with a :class:`StorageError` saying what is kept.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from actionreasoning.errors import ConfigError, LLMError, StorageError
from actionreasoning.reasoners.factory import prepare
from actionreasoning.recording.rerun_log import require_rerun
from actionreasoning.records import FailureCode
from actionreasoning.runs.jobs import (
    TrialJob,
    TrialOutput,
    run_in_processes,
    run_on_ray,
    run_serial,
)
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run_dir import (
    RunManifest,
    append_result,
    digest,
    open_run,
    write_error,
    write_file,
)
from actionreasoning.runs.run_lock import run_lock
from actionreasoning.runs.summary import RunSummary, summarize, summary_markdown
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.provenance import current_provenance, stamp
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.rules import Method
from actionreasoning.trial.runner import TrialSpec
from actionreasoning.world.models import GoalPattern


@dataclass(frozen=True)
class RunConfig:
    """The options of one eval run: its trials' configuration and how to run them."""

    method: Method
    pattern_name: str
    goal: GoalPattern
    trials: int
    seed: int
    out: Path
    config: TrialConfig = TrialConfig()
    snapshots: bool = False
    transcripts: bool = False
    rerun: bool = False
    video: bool = False
    workers: int = 1
    ray: str | None = None

    def trial_config(self) -> TrialConfig:
        """The configuration every trial runs under: the classical script has no backend."""
        if self.method is Method.CLASSICAL:
            return self.config.model_copy(update={"llm": None})
        return self.config

    def manifest(self, trials: TrialConfig | None = None) -> RunManifest:
        """What a resumed run must share with this one; ``trials`` is :meth:`trial_config`
        as prepared for the run, which settles what the backend records (its headers, a
        replay's sampling settings)."""
        return RunManifest.sealed(
            method=str(self.method),
            pattern=self.pattern_name,
            pattern_sha256=digest(self.goal.model_dump_json()),
            seed=self.seed,
            config=trials or self.trial_config(),
            supply=self.goal.supply,
        )


class RunObserver(Protocol):
    """Told what a run resumes and of every trial as it finishes (progress display)."""

    def started(self, total: int, finished: list[TrialResult]) -> None: ...

    def finished(self, result: TrialResult) -> None: ...

    def note(self, line: str) -> None: ...


def check_engine(config: RunConfig) -> None:
    """Refuse engine options that cannot work together, or that lack their package."""
    if config.rerun:
        require_rerun()
    if config.workers > 1 and config.ray:
        raise ConfigError("--workers and --ray exclude each other: Ray places the trials itself")
    llm = config.config.llm
    if llm is not None and llm.record and (config.workers > 1 or config.ray):
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
    trials, run = _prepared(config.trial_config()), RunDir(config.out)
    finished = open_run(config.out, config.manifest(trials))
    results = [r for r in finished if r.trial < config.trials]
    resumed = len(results)
    if observer is not None:
        observer.started(config.trials, list(results))
        if missing := _missing_files(run, config, results):
            observer.note(missing)
    jobs = _jobs(config, trials, {r.trial for r in results})
    provenance = current_provenance()
    started = time.perf_counter()
    with run.results.open("ab", buffering=0) as sink:
        for output in _engine(config, jobs, config.trials - resumed):
            result = stamp(output.result, provenance)
            try:
                append_result(sink, result)
            except OSError as error:
                raise write_error(run.results, error, _kept(len(results))) from error
            results.append(result)
            _write_outputs(run, config, output, _kept(len(results)))
            if observer is not None:
                observer.finished(result)
    mode = None if trials.llm is None or trials.llm.mode is None else str(trials.llm.mode)
    summary = summarize(
        sorted(results, key=lambda r: r.trial),
        time.perf_counter() - started,
        trials.success_rule,
        llm_mode=mode,
        resumed_trials=resumed,
        physics=trials.physics,
        noise=trials.noise,
        answer_errors=trials.answer_errors,
        tools=trials.tools,
    )
    summary, kept = stamp(summary, provenance), _kept(len(results))
    write_file(run.summary, (summary.model_dump_json(indent=2) + "\n").encode(), kept)
    write_file(run.summary_md, summary_markdown(summary).encode(), kept)
    return summary


def _prepared(config: TrialConfig) -> TrialConfig:
    """``config`` with its backend checked and settled for the run (factory.prepare),
    within one trial's wall time."""
    if config.llm is None:
        return config
    limit_s = config.budget.max_wall_s
    try:
        llm = prepare(config.llm, time.monotonic() + limit_s)
    except LLMError as error:
        if error.reason is not FailureCode.TIME_BUDGET:
            raise
        raise LLMError(
            error.reason, f"the start probe took longer than --max-trial-s ({limit_s:g} s)"
        ) from None
    return config.model_copy(update={"llm": llm})


def _missing_files(run: RunDir, config: RunConfig, finished: list[TrialResult]) -> str | None:
    """One line naming the files the run's options ask for that trials finished by an
    earlier session lack (a video that could not be finished, say), and how to make them;
    None if none lacks any."""
    lacking: dict[str, list[int]] = {}
    for result in finished:
        video = run.video(result)
        for kind, wanted, path in (
            ("transcript", config.transcripts, run.transcript(result.trial)),
            ("snapshots", config.snapshots, run.snapshots(result.trial)),
            ("Rerun recording", config.rerun, run.recording(result.trial)),
            ("video", config.video, video),
            # A video's record, where the video is (one written before records were kept).
            ("frame record", config.video and video.exists(), run.frames(result.trial)),
        ):
            if wanted and not path.exists():
                lacking.setdefault(kind, []).append(result.trial)
    if not lacking:
        return None
    what = "; ".join(
        f"{kind} of trial{'s' if len(trials) > 1 else ''} {', '.join(map(str, trials))}"
        for kind, trials in lacking.items()
    )
    return (
        f"missing from {run.root}: {what}, not written when those trials ran; a resume runs no "
        "finished trial again: to make them, run the same command with a new --out"
    )


def _kept(finished: int) -> str:
    return f"{finished} finished trial{'s' if finished != 1 else ''} kept in {RunDir.RESULTS}"


def _jobs(run: RunConfig, config: TrialConfig, done: set[int]) -> Iterator[TrialJob]:
    """The trials not in ``done``, in order, each made when an engine asks for it: a run of
    any length starts at once and holds only the jobs in flight."""
    for trial in range(run.trials):
        if trial in done:
            continue
        spec = TrialSpec(
            method=run.method,
            pattern_name=run.pattern_name,
            goal=run.goal,
            run_seed=run.seed,
            trial=trial,
            config=config,
        )
        yield TrialJob(
            spec=spec,
            snapshots=run.snapshots,
            transcripts=run.transcripts,
            rerun=run.rerun,
            video=run.video,
        )


def _engine(config: RunConfig, jobs: Iterator[TrialJob], count: int) -> Iterator[TrialOutput]:
    """The engine for ``count`` jobs."""
    if config.ray:
        return run_on_ray(jobs, config.ray)
    if config.workers > 1 and count > 1:
        return run_in_processes(jobs, min(config.workers, count))
    return run_serial(jobs)


def _write_outputs(run: RunDir, config: RunConfig, output: TrialOutput, kept: str) -> None:
    """A trial's transcript, pictures, recording, and video with its frame record, written
    after its result line."""
    result = output.result
    trial = result.trial
    files: dict[Path, bytes] = {}
    if config.transcripts:
        files[run.transcript(trial)] = output.transcript.encode()
    if config.snapshots:
        folder = run.snapshots(trial)
        files |= {folder / path: data for path, data in output.pictures.items()}
    if config.rerun:
        files[run.recording(trial)] = output.recording
    if config.video and output.video:
        files[run.video(result)] = output.video
        files[run.frames(trial)] = output.frames
    incomplete = (
        f"not all of trial {trial}'s pictures, transcript, recording, video and frame record "
        "are written"
    )
    for path, data in files.items():
        write_file(path, data, f"{incomplete}; {kept}")
    if config.video and output.video_error:
        raise StorageError(
            f"cannot write {run.video(result)}: the video could not be finished "
            f"({output.video_error}; videos are made in {tempfile.gettempdir()}); {kept}, "
            "without this video; make room, then run the same command again"
        )
