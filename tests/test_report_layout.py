"""Every chart of a report names every method and cuts nothing: drawn by matplotlib's Agg
renderer, every legend and every text of every chart lies inside its figure, for 1 to 6
methods with long labels on two patterns (the first of which one method did not run), and
the stage grids with one row or several."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pytest
from matplotlib.axis import Axis
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.text import Text
from matplotlib.transforms import Bbox
from test_courses import brick
from test_run_dir import result
from test_summary_statistics import write_run

from actionreasoning.agents.answer_errors import AnswerErrors
from actionreasoning.agents.error_kinds import ErrorCategory as C
from actionreasoning.agents.orchestrator import Budgets
from actionreasoning.reasoners.backend import LLMConfig
from actionreasoning.recording.images import grid_figure
from actionreasoning.records import LLMUsage
from actionreasoning.report.collect import Group, labels, load_groups
from actionreasoning.report.plots import (
    courses_figure,
    errors_figure,
    llm_cost_figure,
    refusals_figure,
    success_figure,
)
from actionreasoning.runs.run_dir import RunManifest
from actionreasoning.trial.config import TrialConfig
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scenarios import NOISE
from actionreasoning.world.stages import Stage

PATTERNS = ("pyramid", "a_wall_of_thirteen_bricks_in_running_bond")
USAGE = LLMUsage(calls=2, prompt_tokens=900, completion_tokens=60, latency_s=4.0)


def cut(figure: Figure) -> list[str]:
    """What of ``figure`` reaches past its edges once it is drawn: each axis (its tick labels
    and label, as drawn), legend and other text."""
    canvas = FigureCanvasAgg(figure)
    canvas.draw()
    renderer = canvas.get_renderer()
    axes = [axis for ax in figure.axes for axis in (ax.xaxis, ax.yaxis)]
    of_axes = {id(text) for axis in axes for text in _texts(axis)}
    shown: list[tuple[str, Bbox | None]] = [
        (f"axis labelled {axis.label.get_text()!r}", axis.get_tightbbox(renderer)) for axis in axes
    ]
    for artist in figure.findobj(lambda a: isinstance(a, Legend | Text) and a.get_visible()):
        if isinstance(artist, Legend):
            shown.append(("a legend", artist.get_window_extent(renderer)))
        elif artist.get_text() and id(artist) not in of_axes:
            shown.append((artist.get_text(), artist.get_window_extent(renderer)))
    edges = figure.bbox.padded(0.5)
    return [
        name
        for name, box in shown
        if box is not None and Bbox.union([box, edges]).bounds != edges.bounds
    ]


def _texts(axis: Axis) -> list[Text]:
    """The texts an axis draws (checked with the axis, as drawn)."""
    ticks = [*axis.get_major_ticks(), *axis.get_minor_ticks()]
    return [axis.label, axis.offsetText, *(t.label1 for t in ticks), *(t.label2 for t in ticks)]


def legend_entries(figure: Figure) -> list[str]:
    """The labels of the figure's legends, their wrapped lines joined again."""
    return [" ".join(text.get_text().split()) for legend in figure.legends for text in legend.texts]


def runs(tmp_path: Path, methods: int) -> list[Group]:
    """``methods`` rows of the agents with long labels (noise, answer errors, and other
    models and budgets), each on both patterns but the second row, which did not run the
    first pattern; every trial has bricks on two courses, a model's usage and refused
    answers."""
    made = []
    for m in range(methods):
        spec = f"openai:a-rather-long-model-name-{m}"
        config = TrialConfig(
            physics=PRECISE,
            noise=NOISE["low"],
            answer_errors=AnswerErrors(rate=0.1, persistence=0.5),
            llm=LLMConfig(spec=spec),
            budget=TrialBudget(max_steps=400_000 + m, max_wall_s=3600.0 + m),
            retries=Budgets(regrasps=4 + m),
        )
        for pattern in PATTERNS[1:] if m == 1 else PATTERNS:
            lines = [
                result(trial, success=trial != 1).model_copy(
                    update={
                        "pattern": pattern,
                        "llm": spec,
                        "noise": "low",
                        "bricks": (brick(0.03, 0.2 + m / 10), brick(0.09, 0.5 + trial / 10)),
                        "llm_usage_by_agent": {"pre_grasp": USAGE, "placement_agent": USAGE},
                        "refusals": {"pre_grasp": {C.WRONG_CHOICE: 1 + m}},
                    }
                )
                for trial in range(2)
            ]
            manifest = RunManifest.sealed("agents", pattern, f"{pattern[0]}" * 64, 0, config)
            made.append(write_run(tmp_path / f"{m}_{pattern}", manifest, lines))
    return load_groups(made)


CHARTS: dict[str, Callable[[Sequence[Group]], Figure | None]] = {
    "errors": errors_figure,
    "success": success_figure,
    "courses": courses_figure,
    "llm_cost": llm_cost_figure,
    "refusals": refusals_figure,
}


@pytest.mark.parametrize("methods", range(1, 7))
@pytest.mark.parametrize("chart", CHARTS)
def test_no_chart_cuts_a_legend_or_a_label(tmp_path: Path, chart: str, methods: int) -> None:
    groups = runs(tmp_path, methods)
    figure = CHARTS[chart](groups)
    assert figure is not None
    assert cut(figure) == []
    rows = labels(groups)
    assert len(rows) == methods and all(len(row) > 100 for row in rows)
    entries = legend_entries(figure)
    named = {
        "errors": rows,
        "success": rows,
        "courses": [f"{g.label} · {g.pattern}" for g in groups],
        "llm_cost": [f"{row} {part}" for row in rows for part in ("prompt", "completion")],
        "refusals": ["wrong_choice"],
    }[chart]
    assert entries == named


def test_the_success_chart_names_a_method_that_did_not_run_the_first_pattern(
    tmp_path: Path,
) -> None:
    groups = runs(tmp_path, 3)
    second = labels(groups)[1]
    assert {g.pattern for g in groups if g.label == second} == {PATTERNS[1]}
    assert second in legend_entries(success_figure(groups))


@pytest.mark.parametrize("rows", [1, 2, 6])
def test_no_stage_grid_cuts_a_title_or_a_row_label(rows: int) -> None:
    """A grid of the eight stages of a 480 x 360 close-up, a row per method labelled as the
    report labels it; the last of several rows lacks its last stages."""
    picture = np.full((360, 480, 3), 128, dtype=np.uint8)
    grid = [
        (
            f"agents (openai:a-rather-long-model-name-{r}, tools check), precise\ntrial {r}",
            [(str(stage), picture) for stage in Stage][: 5 if 0 < r == rows - 1 else 8],
        )
        for r in range(rows)
    ]
    figure = grid_figure(grid, titles_on_first_row=True)
    assert cut(figure) == []
    titles = [axis.get_title() for axis in figure.axes if axis.get_title()]
    assert titles == [str(stage).replace("_", " ") for stage in Stage]


def test_the_check_finds_a_legend_and_a_title_past_the_edges() -> None:
    """A positive control: the check above fails where something is cut."""
    figure = Figure(figsize=(3, 2.5))
    axis = figure.subplots()
    axis.plot([0, 1], label="a label far too long to fit a figure three inches wide at all")
    figure.legend(loc="center")
    axis.set_ylabel("a y label far longer than the figure is tall")
    assert set(cut(figure)) == {
        "axis labelled 'a y label far longer than the figure is tall'",
        "a legend",
        "a label far too long to fit a figure three inches wide at all",
    }
