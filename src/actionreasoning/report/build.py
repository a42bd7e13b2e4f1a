"""Write a report of eval runs: tables, plots, stage grids, GIFs on request, the trials'
videos, one HTML page.

The HTML page embeds every picture (data URIs). Videos are copied into the report's
``videos/`` folder and linked from the page relatively, failed trials first.
"""

from __future__ import annotations

import base64
import re
import shutil
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from jinja2 import Environment, PackageLoader, select_autoescape

from actionreasoning.recording.names import VIDEO_FPS
from actionreasoning.records import FailureClass
from actionreasoning.report.collect import Group, load_groups, patterns
from actionreasoning.report.ladder import LADDER_CAPTION, LADDER_COLUMNS
from actionreasoning.report.leaderboard import BOARD_CAPTION, BOARD_COLUMNS
from actionreasoning.report.pairs import PAIR_COLUMNS, PAIRS_CAPTION
from actionreasoning.report.paper_rows import beside_the_paper
from actionreasoning.report.pictures import stage_grid, trial_gif
from actionreasoning.report.plots import (
    course_errors,
    error_distributions,
    llm_cost,
    perception_errors,
    refusal_categories,
    success_rates,
)
from actionreasoning.report.runs import unique
from actionreasoning.report.tables import (
    ALL_TRIALS_NOTE,
    ALL_TRIALS_TITLE,
    AVERAGE,
    COLUMNS,
    COURSES_PLOT,
    MEANS_NOTE,
    PACE_COLUMNS,
    PACE_NOTE,
    REFUSALS_PLOT,
    SUCCESS_NOTE,
    Means,
    Table,
    comparison_table,
    failure_classes_of,
    to_csv,
    to_latex,
    to_markdown,
)
from actionreasoning.runs.run_dir import output_directory
from actionreasoning.runs.summary import CAUGHT_TITLES, COURSE_COLUMNS, categories_in, course_cells
from actionreasoning.trial.results import Refusals, TrialResult

HTML_FILE = "report.html"
COURSES_CAPTION = (
    "Centre offset and rotation error per course (0 on the ground), means ± standard "
    "deviations over all trials' bricks, with the success rule's limits"
)


@dataclass
class Report:
    """The files a report wrote, by kind."""

    directory: Path
    groups: list[Group]
    table: Table
    tables: list[Path] = field(default_factory=list)
    plots: list[tuple[Path, str]] = field(default_factory=list)
    grids: list[tuple[Path, str]] = field(default_factory=list)
    gifs: list[tuple[Path, str]] = field(default_factory=list)
    videos: list[tuple[Path, str]] = field(default_factory=list)
    html: Path | None = None


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_").lower()


def build_report(
    directories: Sequence[Path], out: Path, gifs: bool = False, paper: bool = False
) -> Report:
    """Read the runs in ``directories`` and write the report into ``out`` (created once
    they are read); with ``paper``, also Table I beside the paper's (``paper.md``)."""
    groups = load_groups(directories)
    output_directory(out)
    table = comparison_table(groups)
    report = Report(directory=out, groups=groups, table=table)
    texts = [
        ("table.md", to_markdown(table)),
        ("table.csv", to_csv(table)),
        ("table.tex", to_latex(table)),
    ]
    if paper:
        texts.append(("paper.md", beside_the_paper(table)))
    for name, text in texts:
        (out / name).write_text(text)
        report.tables.append(out / name)
    report.plots.append(
        (error_distributions(groups, out / "errors.png"), "Per-brick errors by method and pattern")
    )
    report.plots.append(
        (
            success_rates(groups, out / "success.png"),
            "Success rate per pattern, with its Wilson 95 % interval",
        )
    )
    courses = course_errors(groups, out / COURSES_PLOT)
    if courses is not None:
        report.plots.append((courses, COURSES_CAPTION))
    cost = llm_cost(groups, out / "llm_cost.png")
    if cost is not None:
        report.plots.append((cost, "LLM tokens per brick and latency per call, by agent"))
    seen = perception_errors(groups, out / "perception.png")
    if seen is not None:
        report.plots.append(
            (seen, "Perception: how far the answers' poses of bricks were from them, by agent")
        )
    refused = refusal_categories(groups, out / REFUSALS_PLOT)
    if refused is not None:
        report.plots.append((refused, "Refused and failed answers per agent, by error category"))
    for pattern in patterns(groups):
        members = [g for g in groups if g.pattern == pattern]
        grid = stage_grid(members, out / f"stages_{_slug(pattern)}.png")
        if grid is not None:
            report.grids.append((grid, f"Stages on {pattern}"))
    if gifs:
        report.gifs = _gifs(groups, out / "gifs")
    report.videos = _videos(groups, out / "videos")
    report.html = write_html(report, directories)
    return report


def _trials(groups: Sequence[Group]) -> Iterator[tuple[Group, TrialResult, str, str]]:
    """Every trial with a file name and a caption for what is made of it."""
    for group in groups:
        seeds = len({r.seed for r in group.results}) > 1  # pooled: trial k of each seed
        for result in group.results:
            trial = f"trial {result.trial}"
            name = f"{_slug(group.label)}_{_slug(group.pattern)}_trial_{result.trial:03d}"
            if seeds:
                trial, name = f"seed {result.seed}, {trial}", f"{name}_seed_{result.seed}"
            status = "success" if result.failure is None else result.failure.reason
            yield group, result, name, f"{group.label} on {group.pattern}, {trial} ({status})"


def _gifs(groups: Sequence[Group], directory: Path) -> list[tuple[Path, str]]:
    made = []
    for group, result, name, caption in _trials(groups):
        snapshots = group.snapshot_dir(result)
        gif = None if snapshots is None else trial_gif(snapshots, directory / f"{name}.gif")
        if gif is not None:
            made.append((gif, caption))
    return made


def _videos(groups: Sequence[Group], directory: Path) -> list[tuple[Path, str]]:
    """The trials' videos copied into ``directory``, failed trials first."""
    found = [
        (result.failure is None, video, name, caption)
        for group, result, name, caption in _trials(groups)
        if (video := group.video(result)) is not None
    ]
    copied = []
    for _, video, name, caption in sorted(found, key=lambda item: item[0]):
        directory.mkdir(parents=True, exist_ok=True)
        copied.append((Path(shutil.copyfile(video, directory / f"{name}.mp4")), caption))
    return copied


def _data_uri(path: Path) -> str:
    kind = "gif" if path.suffix == ".gif" else "png"
    return f"data:image/{kind};base64," + base64.b64encode(path.read_bytes()).decode()


def write_html(report: Report, directories: Sequence[Path]) -> Path:
    """The self-contained page of the report."""
    table = report.table
    column_groups = [*table.patterns, AVERAGE]
    environment = Environment(
        loader=PackageLoader("actionreasoning.report"), autoescape=select_autoescape()
    )
    page = environment.get_template("report.html.j2").render(
        title="actionreasoning report",
        video_fps=VIDEO_FPS,
        runs=[str(d) for d in unique(directories)],
        column_groups=column_groups,
        columns=[f"{title} {'↓' if lower else '↑'}" for _, title, _, _, lower in COLUMNS],
        table_rows=_means_rows(table.means),
        all_trials_rows=_means_rows(table.all_means),
        success_columns=[p if p != AVERAGE else "all" for p in column_groups],
        success_rows=[
            {
                "label": row,
                "cells": [table.success_cell(row, p) for p in column_groups],
            }
            for row in table.rows
        ],
        means_note=MEANS_NOTE,
        all_trials_title=ALL_TRIALS_TITLE,
        all_trials_note=ALL_TRIALS_NOTE,
        success_note=SUCCESS_NOTE,
        board_caption=BOARD_CAPTION,
        board_columns=BOARD_COLUMNS,
        board=table.board,
        ladder_caption=LADDER_CAPTION,
        ladder_columns=LADDER_COLUMNS,
        ladder=[row.cells for row in table.ladder],
        pairs_caption=PAIRS_CAPTION,
        pair_columns=PAIR_COLUMNS,
        pairs=[pair.cells for pair in table.pairs],
        failures=table.failures,
        failure_classes=failure_classes_of(table.failures),
        failure_class_names=list(FailureClass),
        answer_errors=table.answer_errors,
        caught_titles=list(CAUGHT_TITLES.values()),
        premove_refusals=[
            {"label": row, "pattern": pattern, "check": check, "count": n}
            for (row, pattern), counts in table.premove_refusals.items()
            for check, n in counts.items()
        ],
        refusals=[_refusal_table(row, p, counts) for (row, p), counts in table.refusals.items()],
        notes=table.notes,
        pace_note=PACE_NOTE,
        pace_columns=PACE_COLUMNS,
        pace=[row.cells for row in table.pace],
        course_columns=COURSE_COLUMNS,
        courses=[
            {"label": row, "pattern": pattern, "rows": [course_cells(c) for c in courses]}
            for (row, pattern), courses in table.courses.items()
        ],
        plots=[{"data": _data_uri(p), "caption": c} for p, c in report.plots],
        grids=[{"data": _data_uri(p), "caption": c} for p, c in report.grids],
        gifs=[{"data": _data_uri(p), "caption": c} for p, c in report.gifs],
        videos=[
            {"src": p.relative_to(report.directory).as_posix(), "caption": c}
            for p, c in report.videos
        ],
    )
    path = report.directory / HTML_FILE
    path.write_text(page, encoding="utf-8")
    return path


def _means_rows(means: Means) -> list[dict[str, Any]]:
    """Table I's rows as the page shows them: each cell's text, whether it is its column's
    best, and its bootstrap interval."""
    return [
        {
            "label": row,
            "cells": [
                {
                    **dict(zip(("text", "best"), means.cell(row, p, metric), strict=True)),
                    "interval": means.interval_cell(row, p, metric),
                }
                for p in [*means.patterns, AVERAGE]
                for metric, *_ in COLUMNS
            ],
        }
        for row in means.rows
    ]


def _refusal_table(label: str, pattern: str, refusals: Refusals) -> dict[str, Any]:
    """One group's refused answers as the page shows them: a row per agent, a column per
    category that occurs, and the total."""
    shown = categories_in(refusals)
    rows = [
        {"agent": agent, "cells": [counts.get(c, 0) for c in shown], "total": sum(counts.values())}
        for agent, counts in refusals.items()
    ]
    return {"label": label, "pattern": pattern, "categories": shown, "agents": rows}
