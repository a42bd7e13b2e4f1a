"""The pages of `demo`: its one-trial run's summary with the pictures of every stage
(report.md), and the full report of the run with an animation and the video of the build
(report/)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from actionreasoning.recording.names import FINAL_BUILD, STAGE_SHEET, VIDEO_FPS
from actionreasoning.report.build import build_report
from actionreasoning.runs.layout import RunDir

DEMO_TRIAL = 0


@dataclass(frozen=True)
class DemoPages:
    """Where the demo's pages are."""

    markdown: Path
    html: Path


def write_demo_pages(run: RunDir) -> DemoPages:
    """Write the report of the demo run in ``run`` (GIFs on), then report.md, which links
    its pictures, the animation and the video."""
    report = build_report([run.root], run.demo_report, gifs=True)
    assert report.html is not None  # build_report always writes the page
    animation = report.gifs[0][0].relative_to(run.root).as_posix()
    snapshots = run.snapshots(DEMO_TRIAL).relative_to(run.root).as_posix()
    video = report.videos[0][0].relative_to(run.root).as_posix()
    run.demo_page.write_text(
        run.summary_md.read_text()
        + "\n## Stages\n\nStages left to right, bricks top to bottom.\n\n"
        + f"![stages]({snapshots}/{STAGE_SHEET})\n\n## Result\n\n"
        + f"![build]({snapshots}/{FINAL_BUILD})\n"
        + f"![the build, stage by stage]({animation})\n\n"
        + f"[The video of the build]({video}) ({VIDEO_FPS} frames per simulated second).\n"
    )
    return DemoPages(markdown=run.demo_page, html=report.html)
