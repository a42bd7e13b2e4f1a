"""`export lerobot`: a filmed eval run as a LeRobot dataset (format v3.0), an episode per
trial in trial order.

A frame holds the overview camera's image (in the dataset's MP4), the arm's measured joints
and gripper opening (``observation.state``), the command in force (``action``: the joint
targets and the gripper opening), the frame's time in its episode (``frame_index / fps``),
its indices and its task, one per pattern (``Build the pyramid pattern: 6 bricks``). All of
it comes from the run's videos and frame records (``eval --video``); the episodes' metadata
adds each trial's index, seed, success, failure code and bricks placed, so that the
successful trials, demonstrations to learn from, can be picked out. The dataset is written
under ``DIR.partial`` and renamed to ``DIR`` once whole; the run is only read.
"""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from actionreasoning.errors import ConfigError
from actionreasoning.export import lerobot_format as fmt
from actionreasoning.export.stats import Stats, aggregate, as_lists, vector_stats
from actionreasoning.export.tables import write_episodes, write_frames, write_tasks
from actionreasoning.export.video import EpisodeVideo
from actionreasoning.recording.frame_record import FrameRecord
from actionreasoning.recording.names import VIDEO_FPS
from actionreasoning.report.collect import pattern_title
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.markdown import plural
from actionreasoning.runs.run_dir import partial_name, read_results, write_error
from actionreasoning.trial.results import TrialResult

FPS = VIDEO_FPS
#: The trials lacking a recording a refusal names; the rest are counted.
NAMED_LACKING = 10


@dataclass(frozen=True)
class FilmedTrial:
    """A trial of the run, with its video and its frame record."""

    result: TrialResult
    video: Path
    record: FrameRecord

    @property
    def task(self) -> str:
        """What the trial was asked to do, as the dataset's task says it."""
        pattern, bricks = pattern_title(self.result.pattern), len(self.result.bricks)
        return f"Build the {pattern} pattern: {plural(bricks, 'brick')}"

    @property
    def failure(self) -> str | None:
        """Its failure code; None if it succeeded."""
        failure = self.result.failure
        return None if failure is None else str(failure.reason)


@dataclass(frozen=True)
class LeRobotExport:
    """What an export wrote: the dataset's directory, its episodes (and how many of them
    succeeded), frames and tasks."""

    out: Path
    episodes: int
    successes: int
    frames: int
    tasks: tuple[str, ...]

    def describe(self) -> str:
        """``2 episodes (1 successful), 1902 frames, 1 task: a LeRobot v3.0 dataset in DIR/``."""
        return (
            f"{plural(self.episodes, 'episode')} ({self.successes} successful), "
            f"{plural(self.frames, 'frame')}, {plural(len(self.tasks), 'task')}: "
            f"a LeRobot {fmt.CODEBASE_VERSION} dataset in {self.out}/"
        )


def export_lerobot(
    run: Path, out: Path, say: Callable[[str], None] = lambda line: None
) -> LeRobotExport:
    """Write the trials of the eval run ``run`` as the LeRobot dataset ``out`` (a new or
    empty directory), telling ``say`` of each episode as it is written."""
    trials = filmed_trials(run)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out {out} exists and is not an empty directory: choose a new one")
    partial = partial_name(out)
    shutil.rmtree(partial, ignore_errors=True)  # left by an export that was stopped
    try:
        written = _write(trials, partial, out, say)
        os.replace(partial, out)
    except OSError as error:
        raise write_error(
            Path(error.filename or partial), error, f"{run} is untouched and {out} not written"
        ) from error
    finally:
        shutil.rmtree(partial, ignore_errors=True)
    return written


def filmed_trials(run: Path) -> list[FilmedTrial]:
    """The finished trials of ``run`` in trial order, each with its video and frame record;
    a run without them is refused in one line saying how to make them."""
    layout = RunDir(run)
    if not layout.results.is_file():
        raise ConfigError(f"{run} has no {RunDir.RESULTS}: not an eval output directory")
    results = sorted(read_results(layout.results), key=lambda result: result.trial)
    if not results:
        raise ConfigError(f"{layout.results} holds no finished trial: nothing to export")
    found = [(result, layout.video(result), layout.frames(result.trial)) for result in results]
    lacking = [r.trial for r, video, frames in found if not (video.is_file() and frames.is_file())]
    if len(lacking) == len(results):
        raise ConfigError(
            f"{run} has no videos with frame records ({RunDir.VIDEOS}/, {RunDir.FRAMES}/): "
            "run eval with --video, then export that run"
        )
    if lacking:
        named = ", ".join(map(str, lacking[:NAMED_LACKING]))
        if len(lacking) > NAMED_LACKING:
            named += f" and {len(lacking) - NAMED_LACKING} more"
        raise ConfigError(
            f"{run} lacks the video or frame record of trial{'s' if len(lacking) > 1 else ''} "
            f"{named} (a video not finished, or filmed before frame records were kept): run "
            "eval with --video into a new --out"
        )
    return [FilmedTrial(result, video, FrameRecord.read(frames)) for result, video, frames in found]


def _write(
    trials: Sequence[FilmedTrial], root: Path, out: Path, say: Callable[[str], None]
) -> LeRobotExport:
    """Write the dataset of ``trials`` under ``root``, to be renamed ``out``."""
    tasks = list(dict.fromkeys(trial.task for trial in trials))
    video = EpisodeVideo(root / fmt.path_of(fmt.VIDEO_PATH), FPS)
    frames: list[dict[str, np.ndarray]] = []
    episodes: list[dict[str, Any]] = []
    episode_stats: list[dict[str, Stats]] = []
    for episode, trial in enumerate(trials):
        start = video.frames
        columns = _frames(trial.record, episode, start, tasks.index(trial.task))
        stats = {name: vector_stats(values) for name, values in columns.items()}
        stats[fmt.IMAGE_KEY] = video.append(trial.video, len(trial.record))
        frames.append(columns)
        episode_stats.append(stats)
        episodes.append(_episode(trial, episode, start, video.frames, stats))
        say(
            f"episode {episode + 1}/{len(trials)}: trial {trial.result.trial}, "
            f"{trial.failure or 'ok'}, {len(trial.record)} frames"
        )
    video.close()
    assert video.shape is not None  # every trial has a frame
    height, width, _ = video.shape
    features = fmt.features(height, width, FPS)
    write_frames(
        root / fmt.path_of(fmt.DATA_PATH),
        {name: np.concatenate([c[name] for c in frames]) for name in frames[0]},
    )
    write_episodes(
        root / fmt.path_of(fmt.EPISODES_PATH),
        {name: [row[name] for row in episodes] for name in episodes[0]},
        texts={"failure"},
    )
    write_tasks(root / fmt.TASKS_PATH, tasks)
    stats = {name: aggregate([s[name] for s in episode_stats]) for name in episode_stats[0]}
    _write_json(root / fmt.STATS_PATH, {name: as_lists(s) for name, s in stats.items()})
    info = fmt.info(features, FPS, len(trials), video.frames, len(tasks))
    _write_json(root / fmt.INFO_PATH, info)
    return LeRobotExport(
        out=out,
        episodes=len(trials),
        successes=sum(trial.result.success for trial in trials),
        frames=video.frames,
        tasks=tuple(tasks),
    )


def _frames(record: FrameRecord, episode: int, start: int, task: int) -> dict[str, np.ndarray]:
    """The columns of an episode's frames, but its images."""
    n = len(record)
    frame_index = np.arange(n, dtype=np.int64)
    state = np.column_stack([record.joints_rad, record.gripper_m])
    action = np.column_stack([record.joint_targets_rad, record.gripper_target_m])
    return {
        fmt.STATE_KEY: state.astype(np.float32),
        fmt.ACTION_KEY: action.astype(np.float32),
        "timestamp": (frame_index / FPS).astype(np.float32),
        "frame_index": frame_index,
        "episode_index": np.full(n, episode, dtype=np.int64),
        "index": start + frame_index,
        "task_index": np.full(n, task, dtype=np.int64),
    }


def _episode(
    trial: FilmedTrial, episode: int, start: int, end: int, stats: dict[str, Stats]
) -> dict[str, Any]:
    """An episode's row of the episodes' metadata: LeRobot's columns (where its frames,
    video and metadata are, and its statistics), then the trial's."""
    video = f"videos/{fmt.IMAGE_KEY}"
    row: dict[str, Any] = {
        "episode_index": episode,
        "tasks": [trial.task],
        "length": end - start,
        "data/chunk_index": 0,
        "data/file_index": 0,
        "dataset_from_index": start,
        "dataset_to_index": end,
        f"{video}/chunk_index": 0,
        f"{video}/file_index": 0,
        f"{video}/from_timestamp": start / FPS,
        f"{video}/to_timestamp": end / FPS,
        "meta/episodes/chunk_index": 0,
        "meta/episodes/file_index": 0,
    }
    for name, feature_stats in stats.items():
        row |= {f"stats/{name}/{key}": value for key, value in as_lists(feature_stats).items()}
    result = trial.result
    return row | {
        "trial": result.trial,
        "trial_seed": result.trial_seed,
        "success": result.success,
        "failure": trial.failure,
        "bricks_placed": result.bricks_placed,
    }


def _write_json(path: Path, data: dict[str, Any]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=4) + "\n")
