"""Trials as self-contained jobs, and the engines that run them: serial, local worker
processes, or tasks on a Ray cluster.

A job carries everything its trial needs and returns everything it produced (result,
transcript, pictures, video and its frame record, Rerun recording), so only the process
that owns the output directory writes files: the same code serves a worker on this machine
and a Ray task on another.
"""

from __future__ import annotations

import multiprocessing
import os
import socket
import sys
import threading
import time
from collections.abc import Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from itertools import islice
from multiprocessing import resource_tracker

from actionreasoning.errors import ConfigError, EngineError
from actionreasoning.recording.rerun_log import RerunRecorder
from actionreasoning.recording.snapshots import SnapshotRecorder
from actionreasoning.recording.video import FilmFailed, VideoRecorder
from actionreasoning.trial.results import TrialResult
from actionreasoning.trial.runner import TrialSpec, run_trial

PARENT_POLL_S = 0.5
#: Jobs handed out ahead per worker (or Ray CPU): one running, one waiting to start.
IN_FLIGHT = 2
RESUME_HINT = "the finished trials are saved: run the same command to run the rest"


@dataclass(frozen=True)
class TrialJob:
    """One trial to run and what to keep of it."""

    spec: TrialSpec
    snapshots: bool = False
    transcripts: bool = False
    rerun: bool = False
    video: bool = False


@dataclass(frozen=True)
class TrialOutput:
    """What a job produced: the result line, the transcript lines, the pictures, the Rerun
    recording, the MP4 and its frame record (NPZ)."""

    result: TrialResult
    transcript: str = ""
    pictures: dict[str, bytes] = field(default_factory=dict)
    recording: bytes = b""
    video: bytes = b""
    frames: bytes = b""
    #: Why the video could not be made (a full temporary directory, say); "" if it was.
    video_error: str = ""


def execute(job: TrialJob) -> TrialOutput:
    """Run one trial (in whatever process this is) and collect its outputs."""
    snapshots = SnapshotRecorder() if job.snapshots else None
    rerun = RerunRecorder(job.spec) if job.rerun else None
    video = VideoRecorder() if job.video else None
    film, film_error = b"", ""
    try:
        run = run_trial(job.spec, [o for o in (snapshots, rerun, video) if o is not None])
    finally:  # the Rerun stream's threads and the film process end even if the trial raised
        try:
            recording = rerun.rrd() if rerun is not None else b""
        finally:
            try:
                film = video.close() if video is not None else b""
            except FilmFailed as error:  # the trial is whole: its line is kept, then this said
                film_error = str(error)
    transcript = (
        "".join(call.model_dump_json() + "\n" for call in run.transcript) if job.transcripts else ""
    )
    return TrialOutput(
        result=run.result,
        transcript=transcript,
        pictures=snapshots.files if snapshots is not None else {},
        recording=recording,
        video=film,
        frames=video.frame_record() if video is not None else b"",
        video_error=film_error,
    )


def run_serial(jobs: Iterable[TrialJob]) -> Iterator[TrialOutput]:
    """Jobs one after another in this process."""
    for job in jobs:
        yield execute(job)


def _exit_with_parent(parent: int) -> None:
    """In a worker: end at once if the run's process dies (SIGKILL leaves no time to stop
    its workers, which would otherwise finish their trial for nobody and wait forever)."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()


#: multiprocessing's resource tracker frees the semaphores of a pool whose process was killed
#: (SIGKILL), and warns that it did: nothing is left over, so the warning only alarms.
TRACKER_QUIET = "ignore:resource_tracker:UserWarning"


def _quiet_resource_tracker() -> None:
    """Start the resource tracker (a process of its own, started with this interpreter's
    warning options) without its warning about semaphores it frees."""
    if TRACKER_QUIET not in sys.warnoptions:
        sys.warnoptions.append(TRACKER_QUIET)
    resource_tracker.ensure_running()


def run_in_processes(jobs: Iterable[TrialJob], workers: int) -> Iterator[TrialOutput]:
    """Jobs in ``workers`` fresh processes, yielded as they finish (not in trial order).

    Jobs are taken from ``jobs`` as workers free up, IN_FLIGHT per worker at most.
    """
    # spawn, not fork: a worker must not inherit this process's simulator clients or threads.
    context = multiprocessing.get_context("spawn")
    _quiet_resource_tracker()
    pool = ProcessPoolExecutor(
        max_workers=workers,
        mp_context=context,
        initializer=_exit_with_parent,
        initargs=(os.getpid(),),
    )
    queue = iter(jobs)
    pending: set[Future[TrialOutput]] = {
        pool.submit(execute, job) for job in islice(queue, IN_FLIGHT * workers)
    }
    try:
        while pending:
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            pending |= {pool.submit(execute, job) for job in islice(queue, len(done))}
            for future in sorted(done, key=lambda f: f.result().result.trial):
                yield future.result()
    except BrokenProcessPool as error:
        raise EngineError(f"a worker process died ({error}); {RESUME_HINT}") from error
    finally:
        if pending:  # stopped early (Ctrl-C, an error): drop the trials in flight at once
            pool.shutdown(wait=False, cancel_futures=True)
            for child in multiprocessing.active_children():
                child.terminate()
        else:
            pool.shutdown()


def _probe(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast where nothing listens at HOST:PORT (Ray itself retries for minutes)."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not host or not port.isdigit():
        return  # "auto" and the like: Ray looks up the local cluster and fails fast itself
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as error:
        raise ConfigError(f"--ray {address}: no Ray cluster answers there ({error})") from error


def run_on_ray(jobs: Iterable[TrialJob], address: str) -> Iterator[TrialOutput]:
    """Jobs as tasks on the Ray cluster at ``address`` (``auto``: the one on this machine),
    IN_FLIGHT per CPU of the cluster at most."""
    try:
        import ray
    except ImportError as error:
        raise ConfigError(
            "--ray needs Ray: pip install 'actionreasoning[ray]' (or drop --ray)"
        ) from error
    _probe(address)
    try:
        ray.init(address=address, log_to_driver=False, configure_logging=False)
    except (ConnectionError, ValueError, RuntimeError) as error:
        raise ConfigError(f"--ray {address}: cannot join a Ray cluster there ({error})") from error
    try:
        task = ray.remote(num_cpus=1)(execute)
        queue = iter(jobs)
        cpus = max(1, int(ray.cluster_resources().get("CPU", 1)))
        pending = [task.remote(job) for job in islice(queue, IN_FLIGHT * cpus)]
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            pending += [task.remote(job) for job in islice(queue, 1)]
            try:
                output = ray.get(done[0])
            except ray.exceptions.RayError as error:
                summary = str(error).strip().splitlines()[0]
                raise EngineError(f"a Ray task failed ({summary}); {RESUME_HINT}") from error
            yield output
    finally:
        ray.shutdown()
