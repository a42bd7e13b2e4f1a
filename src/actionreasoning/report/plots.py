"""Report plots as PNG: per-brick errors per method, success per pattern, errors per
course, LLM cost and refused answers per agent."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from actionreasoning.agents.error_kinds import ErrorCategory
from actionreasoning.records import LLMUsage
from actionreasoning.report.collect import Group, labels, patterns
from actionreasoning.runs.statistics import wilson
from actionreasoning.runs.summary import categories_in
from actionreasoning.trial.results import sum_refusals

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


def _colours(n: int) -> list[tuple[float, ...]]:
    return [colormaps["tab10"](i % 10) for i in range(n)]


def error_distributions(groups: Sequence[Group], path: Path) -> Path:
    """Box plots of per-brick errors in successful trials: a box per method and pattern."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    figure = Figure(figsize=(4.2 * len(BRICK_METRICS), 3.8), dpi=110)
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
        axis.set_xticks(range(len(cols)), cols)
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    handles = [
        axes[0].bar(0, 0, color=colours[r], alpha=0.7, label=row) for r, row in enumerate(rows)
    ]
    figure.legend(handles=handles, loc="lower center", ncol=min(len(rows), 4), frameon=False)
    figure.suptitle("Per-brick errors over successful trials")
    figure.tight_layout(rect=(0, 0.1, 1, 1))
    figure.savefig(path)
    return path


def success_rates(groups: Sequence[Group], path: Path) -> Path:
    """Bars: success rate of each method on each pattern, with its Wilson 95 % interval as
    an error bar and k/n on top."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    figure = Figure(figsize=(max(4.5, 1.8 * len(cols) * max(1, len(rows) / 2)), 3.6), dpi=110)
    axis = figure.subplots()
    width = 0.8 / len(rows)
    for r, (row, colour) in enumerate(zip(rows, _colours(len(rows)), strict=True)):
        for c, pattern in enumerate(cols):
            group = by_key.get((row, pattern))
            if group is None:
                continue
            x = c + (r - (len(rows) - 1) / 2) * width
            rate = 100.0 * group.summary.success_rate
            axis.bar(x, rate, width * 0.95, color=colour, label=row if c == 0 else None)
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
    axis.set_xticks(range(len(cols)), cols)
    axis.set_ylim(0, 112)
    axis.set_ylabel("success (%), Wilson 95 % CI")
    figure.legend(loc="lower center", ncol=min(len(rows), 3), fontsize=8, frameon=False)
    axis.set_title("Success rate per pattern")
    figure.tight_layout(rect=(0, 0.1, 1, 1))
    figure.savefig(path)
    return path


def course_errors(groups: Sequence[Group], path: Path) -> Path | None:
    """Centre offset and rotation error against course (0 on the ground), over all trials'
    bricks: a line per method (its colour) and pattern (its marker), one standard deviation
    as error bars, the success rule's limit dashed where it fits the scale. None if no
    pattern has two courses."""
    shown = [g for g in groups if len(g.summary.courses) > 1]
    if not shown:
        return None
    rows, cols = labels(groups), patterns(shown)
    colours = _colours(len(rows))
    legend_rows = -(-len(shown) // 3)
    height_in = 3.6 + 0.3 * legend_rows
    figure = Figure(figsize=(8.4, height_in), dpi=110)
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
    figure.legend(
        handles, names, loc="lower center", ncol=min(len(shown), 3), fontsize=8, frameon=False
    )
    figure.suptitle("Errors per course over all trials' bricks (mean ± std)")
    figure.tight_layout(rect=(0, 0.3 * legend_rows / height_in, 1, 1))
    figure.savefig(path)
    return path


def _limits(axis: Axes, limits: Sequence[float], top: float, unit: str) -> None:
    """The success rule's limits on ``axis``: dashed where the errors (up to ``top``) reach
    LIMIT_SHOWN_FROM of them, else named at the top, above the errors."""
    above = [limit for limit in limits if top < LIMIT_SHOWN_FROM * limit]
    if above and top > 0:
        axis.set_ylim(top=top * (1.15 + 0.1 * len(above)))  # room for the notes
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


def llm_cost(groups: Sequence[Group], path: Path) -> Path | None:
    """Tokens per brick and latency per call of every agent, for methods that called a model."""
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
    agents = list(dict.fromkeys(a for row in usage.values() for a in row))
    figure = Figure(figsize=(max(6.0, 1.3 * len(agents) * 2), 3.8), dpi=110)
    tokens, latency = figure.subplots(1, 2)
    width = 0.8 / len(usage)
    x = np.arange(len(agents))
    for r, ((label, row), colour) in enumerate(
        zip(usage.items(), _colours(len(usage)), strict=True)
    ):
        shift = x + (r - (len(usage) - 1) / 2) * width
        per_brick = max(bricks[label], 1)
        prompt = [row.get(a, LLMUsage()).prompt_tokens / per_brick for a in agents]
        completion = [row.get(a, LLMUsage()).completion_tokens / per_brick for a in agents]
        tokens.bar(shift, prompt, width * 0.95, color=colour, alpha=0.55, label=f"{label} prompt")
        tokens.bar(
            shift,
            completion,
            width * 0.95,
            bottom=prompt,
            color=colour,
            label=f"{label} completion",
        )
        calls = [row.get(a, LLMUsage()) for a in agents]
        per_call = [u.latency_s / u.calls if u.calls else 0.0 for u in calls]
        latency.bar(shift, per_call, width * 0.95, color=colour, label=label)
    for axis, title in ((tokens, "tokens per brick"), (latency, "latency per call (s)")):
        axis.set_xticks(x, [a.replace("_", " ") for a in agents], rotation=30, ha="right")
        axis.set_title(title)
        axis.grid(axis="y", alpha=0.3)
    tokens.legend(fontsize=7)
    latency.legend(fontsize=7)
    figure.tight_layout()
    figure.savefig(path)
    return path


def refusal_categories(groups: Sequence[Group], path: Path) -> Path | None:
    """Horizontal bars: the refused and failed answers of each agent, stacked by error
    category; a bar per method (its patterns summed) under each agent. None if no answer was
    refused."""
    by_method = {
        label: sum_refusals(g.summary.refusals for g in groups if g.label == label)
        for label in labels(groups)
    }
    by_method = {label: counts for label, counts in by_method.items() if counts}
    if not by_method:
        return None
    shown = categories_in(*by_method.values())
    bars = [(agent, label) for agent in sum_refusals(by_method.values()) for label in by_method]
    figure = Figure(figsize=(8.5, 1.4 + 0.35 * len(bars)), dpi=110)
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
    names = [agent if len(by_method) == 1 else f"{agent} · {label}" for agent, label in bars]
    axis.set_yticks(y, names, fontsize=8)
    axis.set_xlabel("refused or failed answers (repairs included)")
    axis.set_title("Refused answers per agent, by error category")
    axis.grid(axis="x", alpha=0.3)
    axis.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    figure.tight_layout()
    figure.savefig(path)
    return path
