"""Report plots as PNG: per-brick errors per method, success per pattern, errors per
course, LLM cost and refused answers per agent.

Every chart names every method in a legend under its plots, and nothing is cut: the
figures are laid out by matplotlib's constrained layout, legend labels and long tick labels
are wrapped, a legend takes as many columns as the figure's width holds, and the figure
grows by the legend's height.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TypeVar

import numpy as np
from matplotlib import colormaps
from matplotlib.artist import Artist
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.records import LLMUsage
from actionreasoning.report.collect import Group, labels, patterns
from actionreasoning.runs.statistics import wilson
from actionreasoning.runs.summary import categories_in
from actionreasoning.trial.results import PerceptionErrors, sum_refusals

#: (per-brick field, axis title, scale)
BRICK_METRICS = (
    ("center_offset_cm", "centre offset (cm)", 1.0),
    ("rotation_error_deg", "rotation error (°)", 1.0),
    ("iou", "3D IoU (%)", 100.0),
)

#: (per-course field, axis title, success rule limit, unit)
COURSE_METRICS = (
    ("center_offset_cm", "centre offset (cm)", "max_center_offset_cm", " cm"),
    ("rotation_error_deg", "rotation error (°)", "max_rotation_error_deg", "°"),
)
#: The success rule's limit is drawn if the errors reach this share of it, else named.
LIMIT_SHOWN_FROM = 0.25
COURSE_MARKERS = "os^Dv<>p"  # one per pattern
#: Characters a line of a legend label or a long tick label holds before it is wrapped.
LINE_CHARS = 48
#: The most columns a legend under the plots takes.
LEGEND_COLUMNS = 3
DPI = 110


def _colours(n: int) -> list[tuple[float, float, float, float]]:
    return [colormaps["tab10"](i % 10) for i in range(n)]


def _figure(width_in: float, height_in: float) -> Figure:
    """A figure laid out by constrained layout, with a canvas to measure text on."""
    figure = Figure(figsize=(width_in, height_in), dpi=DPI, layout="constrained")
    FigureCanvasAgg(figure)
    return figure


def wrapped(text: str) -> str:
    """``text`` in lines of at most LINE_CHARS characters."""
    return "\n".join(textwrap.wrap(text, LINE_CHARS, break_on_hyphens=False)) or text


def _legend_below(
    figure: Figure, handles: Sequence[Artist], names: Sequence[str], fontsize: float = 8
) -> None:
    """A legend under the plots with every entry (labels wrapped), in as many columns as the
    figure's width holds (up to LEGEND_COLUMNS); the figure grows by its height."""
    canvas = figure.canvas
    assert isinstance(canvas, FigureCanvasAgg)  # _figure's
    renderer = canvas.get_renderer()
    for columns in range(min(len(handles), LEGEND_COLUMNS), 0, -1):
        legend = figure.legend(
            handles,
            [wrapped(name) for name in names],
            loc="outside lower center",
            ncol=columns,
            fontsize=fontsize,
            frameon=False,
        )
        box = legend.get_window_extent(renderer)
        if box.width <= 0.95 * figure.bbox.width or columns == 1:
            break
        legend.remove()
    figure.set_figheight(figure.get_figheight() + box.height / figure.dpi)


def _save(figure: Figure, path: Path) -> Path:
    figure.savefig(path)
    return path


def error_distributions(groups: Sequence[Group], path: Path) -> Path:
    """Box plots of per-brick errors in successful trials: a box per method and pattern."""
    return _save(errors_figure(groups), path)


def errors_figure(groups: Sequence[Group]) -> Figure:
    """The figure of :func:`error_distributions`."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    figure = _figure(4.2 * len(BRICK_METRICS), 3.8)
    axes = figure.subplots(1, len(BRICK_METRICS))
    width = 0.8 / len(rows)
    colours = _colours(len(rows))
    for axis, (field, title, scale) in zip(axes, BRICK_METRICS, strict=True):
        for r, row in enumerate(rows):
            data, where = [], []
            for c, pattern in enumerate(cols):
                group = by_key.get((row, pattern))
                values = (
                    []
                    if group is None
                    else [
                        getattr(b, field) * scale
                        for t in group.results
                        if t.success
                        for b in t.bricks
                    ]
                )
                if values:
                    data.append(values)
                    where.append(c + (r - (len(rows) - 1) / 2) * width)
            if data:
                boxes = axis.boxplot(
                    data,
                    positions=where,
                    widths=width * 0.9,
                    patch_artist=True,
                    medianprops={"color": "black"},
                )
                for box in boxes["boxes"]:
                    box.set_facecolor(colours[r])
                    box.set_alpha(0.7)
        axis.set_xticks(range(len(cols)), [wrapped(c) for c in cols])
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    handles = [Patch(facecolor=colours[r], alpha=0.7) for r in range(len(rows))]
    figure.suptitle("Per-brick errors over successful trials")
    _legend_below(figure, handles, rows, fontsize=10)
    return figure


def success_rates(groups: Sequence[Group], path: Path) -> Path:
    """Bars: success rate of each method on each pattern, with its Wilson 95 % interval as
    an error bar and k/n on top."""
    return _save(success_figure(groups), path)


def success_figure(groups: Sequence[Group]) -> Figure:
    """The figure of :func:`success_rates`: every method in its legend, whichever patterns
    it ran."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    figure = _figure(max(4.5, 1.8 * len(cols) * max(1, len(rows) / 2)), 3.6)
    axis = figure.subplots()
    width = 0.8 / len(rows)
    colours = _colours(len(rows))
    for r, (row, colour) in enumerate(zip(rows, colours, strict=True)):
        for c, pattern in enumerate(cols):
            group = by_key.get((row, pattern))
            if group is None:
                continue
            x = c + (r - (len(rows) - 1) / 2) * width
            rate = 100.0 * group.summary.success_rate
            axis.bar(x, rate, width * 0.95, color=colour)
            interval = wilson(group.summary.successes, group.summary.trials)
            assert interval is not None  # a group has trials
            low, top = 100.0 * interval.low, 100.0 * interval.high
            axis.errorbar(
                x, rate, yerr=[[rate - low], [top - rate]], color="black", capsize=3, linewidth=1
            )
            axis.text(
                x,
                top + 2,
                f"{group.summary.successes}/{group.summary.trials}",
                ha="center",
                fontsize=8,
            )
    axis.set_xticks(range(len(cols)), [wrapped(c) for c in cols])
    axis.set_ylim(0, 112)
    axis.set_ylabel("success (%), Wilson 95 % CI")
    axis.set_title("Success rate per pattern")
    _legend_below(figure, [Patch(facecolor=colour) for colour in colours], rows)
    return figure


def course_errors(groups: Sequence[Group], path: Path) -> Path | None:
    """Centre offset and rotation error against course (0 on the ground), over all trials'
    bricks: a line per method (its colour) and pattern (its marker), one standard deviation
    as error bars, the success rule's limit dashed where it fits the scale. None if no
    pattern has two courses."""
    figure = courses_figure(groups)
    return None if figure is None else _save(figure, path)


def courses_figure(groups: Sequence[Group]) -> Figure | None:
    """The figure of :func:`course_errors`; None if no pattern has two courses."""
    shown = [g for g in groups if len(g.summary.courses) > 1]
    if not shown:
        return None
    rows, cols = labels(groups), patterns(shown)
    colours = _colours(len(rows))
    figure = _figure(8.4, 3.6)
    axes = figure.subplots(1, len(COURSE_METRICS))
    width = min(0.08, 0.4 / len(shown))  # lines side by side, their bars apart
    for axis, (field, title, limit, unit) in zip(axes, COURSE_METRICS, strict=True):
        top = 0.0
        for i, group in enumerate(shown):
            courses = group.summary.courses
            mean, std = np.array([getattr(c, field) for c in courses]).T
            axis.errorbar(
                [c.course + (i - (len(shown) - 1) / 2) * width for c in courses],
                mean,
                yerr=std,
                color=colours[rows.index(group.label)],
                marker=COURSE_MARKERS[cols.index(group.pattern) % len(COURSE_MARKERS)],
                markersize=5,
                capsize=3,
                label=group.label if len(cols) == 1 else f"{group.label} · {group.pattern}",
            )
            top = max(top, float(np.max(mean + std)))
        limits = {getattr(g.rule, limit) for g in shown if g.rule is not None}
        _limits(axis, sorted(limits), top, unit)
        last = max(c.course for g in shown for c in g.summary.courses)
        axis.set_xticks(range(last + 1))
        axis.set_xlabel("course (0: on the ground)")
        axis.set_ylim(bottom=0)
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    handles, names = axes[0].get_legend_handles_labels()
    figure.suptitle("Errors per course over all trials' bricks (mean ± std)")
    _legend_below(figure, handles, names)
    return figure


def _limits(axis: Axes, limits: Sequence[float], top: float, unit: str) -> None:
    """The success rule's limits on ``axis``: dashed where the errors (up to ``top``) reach
    LIMIT_SHOWN_FROM of them, else named at the top, above the errors."""
    above = [limit for limit in limits if top < LIMIT_SHOWN_FROM * limit]
    drawn = [limit for limit in limits if limit not in above]
    room = [top * (1.15 + 0.1 * len(above))] if above and top > 0 else []  # for the notes
    if drawn:
        room.append(max(top, *drawn) * 1.12)  # for the name above the highest line
    if room:
        axis.set_ylim(top=max(room))
    for limit in limits:
        if limit not in above:
            axis.axhline(limit, color="grey", linestyle="--", linewidth=1)
            axis.annotate(
                f"success limit {limit:g}{unit}",
                (1.0, limit),
                xycoords=("axes fraction", "data"),
                xytext=(-4, 3),
                textcoords="offset points",
                ha="right",
                va="bottom",
                fontsize=8,
                color="grey",
            )
        else:
            axis.text(
                0.98,
                0.97 - 0.07 * above.index(limit),
                f"success limit {limit:g}{unit}, above the scale",
                transform=axis.transAxes,
                ha="right",
                va="top",
                fontsize=8,
                color="grey",
            )


Row = TypeVar("Row")


def _agent_bars(
    rows: Mapping[str, Mapping[str, Row]], inches_per_agent: float
) -> tuple[
    Figure,
    tuple[Axes, Axes],
    list[str],
    list[tuple[str, Mapping[str, Row], tuple[float, float, float, float], np.ndarray]],
]:
    """Two panels of bars by agent, a bar per method side by side: the figure, its panels,
    the agents (in the order first met) and, per method, its label, row, colour and the
    bars' x positions (the agents' at 0, 1, ...)."""
    agents = list(dict.fromkeys(a for row in rows.values() for a in row))
    figure = _figure(max(6.0, inches_per_agent * len(agents) * 2), 3.8)
    left, right = figure.subplots(1, 2)
    width, x = 0.8 / len(rows), np.arange(len(agents))
    bars = [
        (label, row, colour, x + (r - (len(rows) - 1) / 2) * width)
        for r, ((label, row), colour) in enumerate(
            zip(rows.items(), _colours(len(rows)), strict=True)
        )
    ]
    return figure, (left, right), agents, bars


def llm_cost(groups: Sequence[Group], path: Path) -> Path | None:
    """Tokens per brick and latency per call of every agent, for methods that called a model."""
    figure = llm_cost_figure(groups)
    return None if figure is None else _save(figure, path)


def llm_cost_figure(groups: Sequence[Group]) -> Figure | None:
    """The figure of :func:`llm_cost`; None if no method called a model."""
    usage: dict[str, dict[str, LLMUsage]] = {}
    bricks: dict[str, int] = {}
    for group in groups:
        for result in group.results:
            for agent, u in result.llm_usage_by_agent.items():
                if u.calls:
                    row = usage.setdefault(group.label, {})
                    row[agent] = row.get(agent, LLMUsage()) + u
            bricks[group.label] = bricks.get(group.label, 0) + len(result.bricks)
    if not usage:
        return None
    figure, (tokens, latency), agents, bars = _agent_bars(usage, 1.3)
    x, width = np.arange(len(agents)), 0.8 / len(usage)
    for label, method, colour, shift in bars:
        per_brick = max(bricks[label], 1)
        prompt = [method.get(a, LLMUsage()).prompt_tokens / per_brick for a in agents]
        completion = [method.get(a, LLMUsage()).completion_tokens / per_brick for a in agents]
        tokens.bar(shift, prompt, width * 0.95, color=colour, alpha=0.55, label=f"{label} prompt")
        tokens.bar(
            shift,
            completion,
            width * 0.95,
            bottom=prompt,
            color=colour,
            label=f"{label} completion",
        )
        calls = [method.get(a, LLMUsage()) for a in agents]
        per_call = [u.latency_s / u.calls if u.calls else 0.0 for u in calls]
        latency.bar(shift, per_call, width * 0.95, color=colour)
    for axis, title in ((tokens, "tokens per brick"), (latency, "latency per call (s)")):
        axis.set_xticks(x, [a.replace("_", " ") for a in agents], rotation=30, ha="right")
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    handles, names = tokens.get_legend_handles_labels()
    _legend_below(figure, handles, names)
    return figure


def perception_errors(groups: Sequence[Group], path: Path) -> Path | None:
    """Bars: how far each agent's answers' poses of bricks were from them (mean, a tick at
    the largest), in the plane and in yaw, a bar per method that saw pictures. None if no
    method did."""
    figure = perception_figure(groups)
    return None if figure is None else _save(figure, path)


def perception_figure(groups: Sequence[Group]) -> Figure | None:
    """The figure of :func:`perception_errors`; None if no method saw pictures."""
    errors: dict[str, dict[str, PerceptionErrors]] = {}
    for group in groups:
        for result in group.results:
            for agent, seen in result.perception.items():
                row = errors.setdefault(group.label, {})
                row[agent] = row.get(agent, PerceptionErrors()) + seen
    if not errors:
        return None
    figure, (offset, yaw), agents, bars = _agent_bars(errors, 1.6)
    x, width = np.arange(len(agents)), 0.8 / len(errors)
    for label, method, colour, shift in bars:
        each = [method.get(a, PerceptionErrors()) for a in agents]
        for axis, mean, most in (
            (
                offset,
                [e.centre_offset_cm_mean for e in each],
                [e.centre_offset_cm_max for e in each],
            ),
            (yaw, [e.yaw_error_deg_mean for e in each], [e.yaw_error_deg_max for e in each]),
        ):
            axis.bar(shift, mean, width * 0.95, color=colour, label=label)
            axis.scatter(shift, most, marker="_", s=200, color="black", zorder=3)
    for axis, title in ((offset, "centre offset (cm)"), (yaw, "yaw error (°)")):
        axis.set_xticks(x, [a.replace("_", " ") for a in agents])
        axis.set_title(f"{title}: mean, — largest")
        axis.grid(axis="y", alpha=0.3)
    handles, names = offset.get_legend_handles_labels()
    _legend_below(figure, handles, names)
    return figure


def refusal_categories(groups: Sequence[Group], path: Path) -> Path | None:
    """Horizontal bars: the refused and failed answers of each agent, stacked by error
    category; a bar per method (its patterns summed) under each agent. None if no answer was
    refused."""
    figure = refusals_figure(groups)
    return None if figure is None else _save(figure, path)


def refusals_figure(groups: Sequence[Group]) -> Figure | None:
    """The figure of :func:`refusal_categories`; None if no answer was refused."""
    by_method = {
        label: sum_refusals(g.summary.refusals for g in groups if g.label == label)
        for label in labels(groups)
    }
    by_method = {label: counts for label, counts in by_method.items() if counts}
    if not by_method:
        return None
    shown = categories_in(*by_method.values())
    bars = [(agent, label) for agent in sum_refusals(by_method.values()) for label in by_method]
    names = [
        wrapped(agent if len(by_method) == 1 else f"{agent} · {label}") for agent, label in bars
    ]
    # 0.35 in a bar of one line of name, 0.15 in more for each further line
    figure = _figure(8.5, 1.4 + sum(0.35 + 0.15 * name.count("\n") for name in names))
    axis = figure.subplots()
    y = np.arange(len(bars))[::-1]
    left = np.zeros(len(bars))
    # tab20's dark shades, then its light ones: neighbouring categories look apart.
    colours = {c: colormaps["tab20"](i * 2 % 20 + i // 10) for i, c in enumerate(ErrorCategory)}
    for category in shown:
        widths = np.array(
            [by_method[label].get(agent, {}).get(category, 0) for agent, label in bars]
        )
        axis.barh(y, widths, left=left, color=colours[category], label=str(category))
        left += widths
    axis.set_yticks(y, names, fontsize=8)
    axis.set_xlabel("refused or failed answers (repairs included)")
    axis.set_title("Refused answers per agent, by error category")
    axis.grid(axis="x", alpha=0.3)
    handles, categories = axis.get_legend_handles_labels()
    _legend_below(figure, handles, categories, fontsize=7)
    return figure
