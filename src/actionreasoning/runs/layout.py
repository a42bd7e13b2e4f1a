"""The layout of an eval output directory, in one place: what `eval` writes there, what
`report` reads back, and what `demo` adds and replaces.

    results.jsonl                    one line per finished trial
    run.json                         the run: method, pattern, seed, trial config and its hash
    summary.json, summary.md         written at the end of a run
    run.lock                         held while a run writes (run_lock.py)
    transcripts/trial_NNN.jsonl      every agent call of trial NNN (--transcripts)
    snapshots/trial_NNN/...          its pictures (--snapshots): stages.png, final_build.png,
                                     frames/ and a close-up per stage
    rerun/trial_NNN.rrd              its Rerun recording (--rerun): open with `rerun FILE`
    videos/trial_NNN_OUTCOME.mp4     its video (--video); OUTCOME is ok or the failure code
    frames/trial_NNN.npz             the video's frame record (--video): per frame, the joints
                                     and gripper measured and commanded (frame_record.py)
    report.md, report/               the demo's pages (`demo` only)
    .actionreasoning-demo            marks a directory `demo` may write into again
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from actionreasoning.trial.results import TrialResult


@dataclass(frozen=True)
class RunDir:
    """An eval output directory, its files named by what they hold."""

    root: Path

    RESULTS: ClassVar[str] = "results.jsonl"
    MANIFEST: ClassVar[str] = "run.json"
    SUMMARY: ClassVar[str] = "summary.json"
    SUMMARY_MD: ClassVar[str] = "summary.md"
    LOCK: ClassVar[str] = "run.lock"
    TRANSCRIPTS: ClassVar[str] = "transcripts"
    SNAPSHOTS: ClassVar[str] = "snapshots"
    RERUN: ClassVar[str] = "rerun"
    VIDEOS: ClassVar[str] = "videos"
    FRAMES: ClassVar[str] = "frames"
    DEMO_PAGE: ClassVar[str] = "report.md"
    DEMO_REPORT: ClassVar[str] = "report"
    DEMO_MARKER: ClassVar[str] = ".actionreasoning-demo"
    #: What a demo writes, all removed before the next demo into the same directory.
    DEMO_FILES: ClassVar[tuple[str, ...]] = (RESULTS, MANIFEST, SUMMARY, SUMMARY_MD, DEMO_PAGE)
    DEMO_FOLDERS: ClassVar[tuple[str, ...]] = (SNAPSHOTS, VIDEOS, FRAMES, DEMO_REPORT)

    @property
    def results(self) -> Path:
        return self.root / self.RESULTS

    @property
    def manifest(self) -> Path:
        return self.root / self.MANIFEST

    @property
    def summary(self) -> Path:
        return self.root / self.SUMMARY

    @property
    def summary_md(self) -> Path:
        return self.root / self.SUMMARY_MD

    @property
    def lock(self) -> Path:
        return self.root / self.LOCK

    def transcript(self, trial: int) -> Path:
        """Where trial ``trial``'s agent calls are."""
        return self.root / self.TRANSCRIPTS / f"{trial_name(trial)}.jsonl"

    def snapshots(self, trial: int) -> Path:
        """The folder of trial ``trial``'s pictures."""
        return self.root / self.SNAPSHOTS / trial_name(trial)

    def recording(self, trial: int) -> Path:
        """Where trial ``trial``'s Rerun recording is."""
        return self.root / self.RERUN / f"{trial_name(trial)}.rrd"

    def video(self, result: TrialResult) -> Path:
        """Where the video of the trial ``result`` is the line of is, named by its failure
        code (``ok`` if none)."""
        outcome = "ok" if result.failure is None else str(result.failure.reason)
        return self.root / self.VIDEOS / f"{trial_name(result.trial)}_{outcome}.mp4"

    def frames(self, trial: int) -> Path:
        """Where trial ``trial``'s frame record is (its video's joints and commands)."""
        return self.root / self.FRAMES / f"{trial_name(trial)}.npz"

    @property
    def demo_page(self) -> Path:
        return self.root / self.DEMO_PAGE

    @property
    def demo_report(self) -> Path:
        return self.root / self.DEMO_REPORT

    @property
    def demo_marker(self) -> Path:
        return self.root / self.DEMO_MARKER


def trial_name(trial: int) -> str:
    """How files and folders of trial ``trial`` are named: ``trial_007``."""
    return f"trial_{trial:03d}"
