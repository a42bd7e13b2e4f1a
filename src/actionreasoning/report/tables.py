"""The paper's Table I: methods in rows; per pattern and on average, rotation error (°),
centre offset (cm) and IoU (%), means over successful trials with their bootstrap
intervals; the same over all trials beside it (where a method that succeeded in no trial of
a pattern has its figures); as markdown, CSV and LaTeX. A method's Average is given only
where it has figures on every pattern. Success comes with its Wilson interval. Then the
leaderboard and the paired comparisons (McNemar's test). Rows and pattern columns are the
groups of collect.py; the notes say how runs differ. Runs with answer errors get a table of
what was corrupted and what caught it, runs with refused answers a table per group of them
by agent and error category, and runs whose checks refused answers nobody corrupted a list
of those checks. Every group gets its bricks set down and within the success rule (before
the first failure, too), its cycle time, and a table of its errors per course.
"""

from __future__ import annotations

import csv
import io
from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from actionreasoning.agents.answer_errors import Caught
from actionreasoning.records import FailureClass, FailureCode
from actionreasoning.report.collect import Group, condition_notes, labels, patterns
from actionreasoning.report.ladder import LadderRow, ladder_lines, ladders
from actionreasoning.report.leaderboard import board_lines, board_rows
from actionreasoning.report.pairs import Pair, pair_lines, paired_comparisons
from actionreasoning.runs.courses import CourseMetrics
from actionreasoning.runs.markdown import table_lines
from actionreasoning.runs.statistics import BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, Interval, wilson
from actionreasoning.runs.summary import (
    CAUGHT_TITLES,
    AnswerErrorTotals,
    MetricStats,
    RunSummary,
    category_table,
    course_table,
    failure_classes,
    success_text,
)
from actionreasoning.trial.results import Refusals

#: (summary metric, column title, scale, digits, lower is better)
COLUMNS = (
    ("rotation_error_deg", "Rot. Err", 1.0, 3, True),
    ("center_offset_cm", "Ctr. Off.", 1.0, 3, True),
    ("iou", "IoU", 100.0, 2, False),
)
AVERAGE = "Average"  # Table I's last column group; for success counts, the total
MEANS_NOTE = (
    "Means over successful trials (per-brick values averaged per trial), each pattern's with "
    f"a bootstrap 95 % interval in brackets ({BOOTSTRAP_RESAMPLES} resamples, seed "
    f"{BOOTSTRAP_SEED}); {AVERAGE}: the mean over the patterns, given only for a method with "
    "figures on every pattern (a dash otherwise: a mean over other patterns does not "
    "compare); the best of each column in bold."
)
ALL_TRIALS_TITLE = "Table I over all trials"
ALL_TRIALS_NOTE = (
    "The same over all trials, failed ones included (a method that succeeded in no trial of "
    "a pattern has its figures here): means, each pattern's with its bootstrap 95 % "
    f"interval; {AVERAGE} only for a method that ran every pattern."
)
SUCCESS_NOTE = (
    "Success: successful trials of all, the rate and its Wilson 95 % interval (all: the "
    "patterns' trials together)."
)
#: The chart of refused answers by agent and category, beside the tables.
REFUSALS_PLOT = "refusals.png"
#: The plot of errors per course, beside the per-course tables.
COURSES_PLOT = "courses.png"
PACE_COLUMNS = (
    "Method",
    "Pattern",
    "Set down",
    "Within the rule",
    "Within the rule before the first failure",
    "Cycle time (simulated s / brick set down)",
    "Set down an hour",
    "Simulated s / brick within the rule",
)
PACE_NOTE = (
    "Bricks a trial set down on their targets, whatever their errors, and those within the "
    "success rule (in all, and before the first brick out of it), means per trial; the cycle "
    "time: simulated seconds per brick set down and the bricks set down an hour, and the "
    "simulated seconds per brick within the rule. A dash where a figure is unknown (lines "
    "of an earlier version) or there is no such brick."
)


@dataclass(frozen=True)
class FailureRow:
    """How often one method failed one way on one pattern, with the first such trial."""

    label: str
    pattern: str
    reason: FailureCode
    count: int
    trial: int
    detail: str


@dataclass(frozen=True)
class AnswerErrorRow:
    """What eval --answer-errors corrupted in one method's runs on one pattern, and what
    caught it, summed over their trials."""

    label: str
    pattern: str
    totals: AnswerErrorTotals

    @property
    def kinds(self) -> str:
        return ", ".join(f"{kind} {n}" for kind, n in self.totals.by_kind.items()) or "–"

    @property
    def caught(self) -> str:
        """The checks that caught them (each with its count; where lines predate those
        counts, what stopped each answer, flat)."""
        if not self.totals.caught:
            return ", ".join(f"{check} {n}" for check, n in self.totals.caught_by.items()) or "–"
        checks = {check: sum(row.values()) for check, row in self.totals.checks.items()}
        return ", ".join(f"{check} {n}" for check, n in checks.items()) or "–"

    @property
    def where(self) -> list[int]:
        """How many were caught before the move, after it, missed, and stopped the trial
        (CAUGHT_TITLES' order)."""
        return [sum(row.get(caught, 0) for row in self.totals.caught.values()) for caught in Caught]

    @property
    def led_to(self) -> str:
        """What the misses led to, summed over kinds."""
        return _summed(self.totals.led_to.values())

    @property
    def would_catch(self) -> str:
        """The checks the misses failed that the run did not enforce, summed over kinds."""
        return _summed(self.totals.would_catch.values())

    @property
    def refused_as(self) -> str:
        """Each kind with the categories its refused answers got (kind -> category n)."""
        pairs = [
            f"{kind} → {category} {n}"
            for kind, categories in self.totals.refused_as.items()
            for category, n in categories.items()
        ]
        return ", ".join(pairs) or "–"


def _summed(rows: Iterable[Mapping[str, int]]) -> str:
    """Counts (name -> count, a row per kind) summed over the rows, as ``name n, ...``."""
    total = Counter[str]()
    for row in rows:
        total.update(row)
    return ", ".join(f"{name} {n}" for name, n in sorted(total.items())) or "–"


@dataclass(frozen=True)
class PaceRow:
    """How much one method's trials on one pattern built and how fast, means per trial:
    the bricks set down whatever their errors (None where the lines do not tell), those
    within the success rule, and those before the first brick out of it (None where the
    rule is unknown); simulated seconds per brick set down, the bricks set down an hour,
    and seconds per brick within the rule (None where the physics is unknown or there is no
    such brick)."""

    label: str
    pattern: str
    bricks: int  # the pattern's
    set_down: float | None
    within: float
    before_failure: float | None
    seconds_per_set_down: float | None
    set_down_per_hour: float | None
    seconds_per_within: float | None

    @property
    def cells(self) -> list[str]:
        """The row as shown: PACE_COLUMNS."""

        def shown(value: float | None, digits: int, of: bool = False) -> str:
            if value is None:
                return "–"
            return f"{value:.{digits}f}" + (f" of {self.bricks}" if of else "")

        return [
            self.label,
            self.pattern,
            shown(self.set_down, 2, of=True),
            shown(self.within, 2, of=True),
            shown(self.before_failure, 2, of=True),
            shown(self.seconds_per_set_down, 1),
            shown(self.set_down_per_hour, 0),
            shown(self.seconds_per_within, 1),
        ]


@dataclass(frozen=True)
class AllTrialsRow:
    """A method's means over all trials of a pattern it succeeded on in none (Table I has
    dashes there), for the terminal's ``LABEL, all trials`` row."""

    label: str
    pattern: str
    stats: dict[str, MetricStats]  # metric -> over all trials


@dataclass(frozen=True)
class Means:
    """Table I's figures over one set of trials (the successful ones, or all): a value per
    (row, pattern or Average, metric), None where there is none (no such trial; for Average,
    a row without a value on every pattern), and each (row, pattern)'s statistics, with the
    bootstrap interval of each mean."""

    rows: list[str]
    patterns: list[str]
    values: dict[tuple[str, str, str], float | None]
    stats: dict[tuple[str, str], dict[str, MetricStats]]

    def best(self, pattern: str, metric: str) -> float | None:
        """The best value of a column, for bold type; None with fewer than two values."""
        lower = next(c[4] for c in COLUMNS if c[0] == metric)
        found = [v for r in self.rows if (v := self.values[(r, pattern, metric)]) is not None]
        if len(found) < 2:
            return None
        return min(found) if lower else max(found)

    def cell(self, row: str, pattern: str, metric: str) -> tuple[str, bool]:
        """A formatted cell and whether it is the column's best."""
        value = self.values[(row, pattern, metric)]
        if value is None:
            return "–", False
        _, _, scale, digits, _ = next(c for c in COLUMNS if c[0] == metric)
        return f"{value * scale:.{digits}f}", value == self.best(pattern, metric)

    def interval_cell(self, row: str, pattern: str, metric: str) -> str:
        """The bootstrap interval of a cell's mean, ``[0.441, 0.618]``; empty where none."""
        stats = self.stats.get((row, pattern), {}).get(metric)
        if stats is None or stats.ci_low is None or stats.ci_high is None:
            return ""
        _, _, scale, digits, _ = next(c for c in COLUMNS if c[0] == metric)
        return f"[{stats.ci_low * scale:.{digits}f}, {stats.ci_high * scale:.{digits}f}]"


def means_of(
    groups: Sequence[Group], over: Callable[[RunSummary], dict[str, MetricStats]]
) -> Means:
    """Table I's figures of ``groups`` over the trials ``over`` picks from a summary; a row's
    Average is the mean over the patterns only if it has a value on every one of them."""
    rows, cols = labels(groups), patterns(groups)
    stats = {(g.label, g.pattern): over(g.summary) for g in groups}
    values: dict[tuple[str, str, str], float | None] = {}
    for row in rows:
        for metric, *_ in COLUMNS:
            found = [stats[(row, p)][metric].mean if (row, p) in stats else None for p in cols]
            values |= {(row, p, metric): mean for p, mean in zip(cols, found, strict=True)}
            known = [mean for mean in found if mean is not None]
            average = float(np.mean(known)) if len(known) == len(cols) else None
            values[(row, AVERAGE, metric)] = average
    return Means(rows=rows, patterns=cols, values=values, stats=stats)


@dataclass(frozen=True)
class Table:
    """Table I over successful trials (``means``) and over all trials (``all_means``), with
    every table that goes with it."""

    rows: list[str]
    patterns: list[str]
    means: Means  # over successful trials
    all_means: Means  # over all trials
    success: dict[tuple[str, str], tuple[int, int]]  # (row, pattern) -> (successes, trials);
    # (row, Average): summed over the patterns
    failures: list[FailureRow]
    notes: list[str]  # how the runs' conditions differ (collect.condition_notes)
    answer_errors: list[AnswerErrorRow]  # the groups run with answer errors
    refusals: dict[tuple[str, str], Refusals]  # (row, pattern) -> refused answers, where any
    # (row, pattern) -> answers nobody corrupted that a pre-move check, sigma_1 or sigma_6
    # refused, by gate:check, where any
    premove_refusals: dict[tuple[str, str], dict[str, int]]
    pace: list[PaceRow]  # a row per group
    courses: dict[tuple[str, str], list[CourseMetrics]]  # (row, pattern) -> its courses, if
    # its lines measured bricks
    board: list[list[str]]  # the leaderboard, a row per group (leaderboard.BOARD_COLUMNS)
    pairs: list[Pair]  # rows run on the same trials, compared
    ladder: list[LadderRow]  # the rungs of verification under each condition

    @property
    def all_trials(self) -> list[AllTrialsRow]:
        """A row of means over all trials for each method and pattern without a success."""
        return [
            AllTrialsRow(label, pattern, stats)
            for (label, pattern), stats in self.all_means.stats.items()
            if not self.success[(label, pattern)][0]
        ]

    @property
    def course_plot(self) -> bool:
        """Whether a pattern has two courses or more, so that plots.course_errors draws."""
        return any(len(courses) > 1 for courses in self.courses.values())

    def cell(self, row: str, pattern: str, metric: str) -> tuple[str, bool]:
        """A cell of Table I over successful trials, and whether it is its column's best."""
        return self.means.cell(row, pattern, metric)

    def success_cell(self, row: str, pattern: str) -> str:
        """Successful trials out of all with the rate's Wilson interval, or a dash where the
        method did not run the pattern."""
        if (row, pattern) not in self.success:
            return "–"
        return success_text(*self.success[(row, pattern)])

    def success_interval(self, row: str, pattern: str) -> Interval | None:
        """The Wilson 95 % interval of a success rate; None where the method did not run
        the pattern."""
        if (row, pattern) not in self.success:
            return None
        return wilson(*self.success[(row, pattern)])


def comparison_table(groups: Sequence[Group]) -> Table:
    """Table I from grouped runs, over successful trials and over all (see :func:`means_of`)."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    success: dict[tuple[str, str], tuple[int, int]] = {}
    for row in rows:
        for pattern in cols:
            group = by_key.get((row, pattern))
            if group is not None:
                success[(row, pattern)] = (group.summary.successes, group.summary.trials)
        counts = [success[(row, p)] for p in cols if (row, p) in success]
        success[(row, AVERAGE)] = (sum(c[0] for c in counts), sum(c[1] for c in counts))
    return Table(
        rows=rows,
        patterns=cols,
        means=means_of(groups, lambda summary: summary.successful),
        all_means=means_of(groups, lambda summary: summary.all_trials),
        success=success,
        failures=_failures(groups),
        notes=condition_notes(groups),
        answer_errors=[
            AnswerErrorRow(g.label, g.pattern, g.summary.answer_errors)
            for g in groups
            if g.summary.answer_errors is not None
        ],
        refusals={(g.label, g.pattern): g.summary.refusals for g in groups if g.summary.refusals},
        premove_refusals={
            (g.label, g.pattern): g.summary.premove_refusals
            for g in groups
            if g.summary.premove_refusals
        },
        pace=[_pace(g) for g in groups],
        courses={(g.label, g.pattern): g.summary.courses for g in groups if g.summary.courses},
        board=board_rows(groups),
        pairs=paired_comparisons(groups),
        ladder=ladders(groups),
    )


def _pace(group: Group) -> PaceRow:
    summary, time = group.summary, group.summary.cycle_time
    return PaceRow(
        label=group.label,
        pattern=group.pattern,
        bricks=summary.bricks_per_trial,
        set_down=summary.bricks_set_down_mean,
        within=summary.bricks_placed_mean,
        before_failure=summary.placed_before_first_failure_mean,
        seconds_per_set_down=None if time is None else time.seconds_per_brick_set_down,
        set_down_per_hour=None if time is None else time.bricks_set_down_per_hour,
        seconds_per_within=None if time is None else time.seconds_per_brick,
    )


def _failures(groups: Sequence[Group]) -> list[FailureRow]:
    """The failure taxonomy: per method and pattern, each reason code with an example."""
    rows = []
    for group in groups:
        for reason, count in group.summary.failures.items():
            example = next(
                r for r in group.results if r.failure is not None and r.failure.reason == reason
            )
            rows.append(
                FailureRow(
                    label=group.label,
                    pattern=group.pattern,
                    reason=reason,
                    count=count,
                    trial=example.trial,
                    detail=example.failure.detail if example.failure else "",
                )
            )
    return rows


def failure_classes_of(
    rows: Sequence[FailureRow],
) -> dict[tuple[str, str], dict[FailureClass, int]]:
    """Per (method row, pattern): its failed trials counted by class."""
    counts: dict[tuple[str, str], Counter[FailureCode]] = {}
    for row in rows:
        counts.setdefault((row.label, row.pattern), Counter())[row.reason] += row.count
    return {key: failure_classes(reasons) for key, reasons in counts.items()}


def _means_lines(means: Means) -> list[str]:
    """Table I's figures as a markdown table (the best of each column in bold)."""
    groups = [*means.patterns, AVERAGE]
    header = ["Method"] + [
        f"{p}: {title} {'↓' if lower else '↑'}" for p in groups for _, title, _, _, lower in COLUMNS
    ]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for row in means.rows:
        cells = [row]
        for pattern in groups:
            for metric, *_ in COLUMNS:
                text, best = means.cell(row, pattern, metric)
                interval = means.interval_cell(row, pattern, metric)
                cells.append(" ".join(filter(None, (f"**{text}**" if best else text, interval))))
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def to_markdown(table: Table) -> str:
    """Table I as a markdown table over successful trials and another over all trials, then
    success per pattern."""
    groups = [*table.patterns, AVERAGE]
    lines = [*_means_lines(table.means), "", MEANS_NOTE, ""]
    lines += [f"{ALL_TRIALS_TITLE}:", "", *_means_lines(table.all_means), "", ALL_TRIALS_NOTE, ""]
    lines += [
        "| Method | "
        + " | ".join(f"{p if p != AVERAGE else 'all'}: success" for p in groups)
        + " |",
        "|---" * (len(groups) + 1) + "|",
    ]
    for row in table.rows:
        lines.append(f"| {row} | " + " | ".join(table.success_cell(row, p) for p in groups) + " |")
    lines += ["", SUCCESS_NOTE, "", *board_lines(table.board), ""]
    if table.ladder:
        lines += [*ladder_lines(table.ladder), ""]
    if table.pairs:
        lines += [*pair_lines(table.pairs), ""]
    if table.failures:
        lines += [
            "Failed trials by what ended them: reasoning (the answers) or physics (the world, "
            "after answers the checks accepted):",
            "",
            "| Method | Pattern | " + " | ".join(FailureClass) + " |",
            "|---" * (2 + len(FailureClass)) + "|",
            *(
                f"| {label} | {pattern} | " + " | ".join(map(str, counts.values())) + " |"
                for (label, pattern), counts in failure_classes_of(table.failures).items()
            ),
            "",
            "| Method | Pattern | Failure reason | Class | Meaning | Trials | Example |",
            "|---|---|---|---|---|---|---|",
            *(
                f"| {f.label} | {f.pattern} | `{f.reason}` | {f.reason.failure_class} | "
                f"{f.reason.meaning} | {f.count} | trial {f.trial}: {f.detail.replace('|', '/')} |"
                for f in table.failures
            ),
        ]
    else:
        lines.append("No trial failed.")
    if table.answer_errors:
        where = " | ".join(CAUGHT_TITLES.values())
        lines += [
            "",
            f"| Method | Pattern | Answer error rate | Persistence | Corrupted | By kind | {where} "
            "| Caught by | Missed: led to | Missed: would be caught by | Refused as |",
            "|---" * 15 + "|",
            *(
                f"| {a.label} | {a.pattern} | {a.totals.rate:g} | {a.totals.persistence:g} | "
                f"{a.totals.corrupted} | {a.kinds} | {' | '.join(map(str, a.where))} | "
                f"{a.caught} | {a.led_to} | {a.would_catch} | {a.refused_as} |"
                for a in table.answer_errors
            ),
        ]
    if table.premove_refusals:
        lines += [
            "",
            "Answers nobody corrupted, refused before the move by a pre-move check, σ1 or σ6 "
            "(each a check refusing an answer its reasoner believed right):",
            "",
            "| Method | Pattern | Check | Answers |",
            "|---|---|---|---|",
            *(
                f"| {row} | {pattern} | `{check}` | {n} |"
                for (row, pattern), counts in table.premove_refusals.items()
                for check, n in counts.items()
            ),
        ]
    for (row, pattern), counts in table.refusals.items():
        lines += [
            "",
            f"Refused and failed answers of {row} on {pattern}, by agent and error category:",
            "",
            *category_table("Agent", counts),
        ]
    if table.refusals:
        lines += ["", f"![Refused answers by agent and error category]({REFUSALS_PLOT})"]
    lines += ["", *_pace_and_course_lines(table)]
    if table.notes:
        lines += ["", *(f"- {note}" for note in table.notes)]
    return "\n".join(lines) + "\n"


def _pace_and_course_lines(table: Table) -> list[str]:
    """Bricks before the first failure and cycle time, a row per group; then a table of
    errors per course for each group, and the plot of them."""
    lines = [f"{PACE_NOTE}:", "", *table_lines(PACE_COLUMNS, [row.cells for row in table.pace])]
    for (row, pattern), courses in table.courses.items():
        lines += [
            "",
            f"Per course of {row} on {pattern} (0 on the ground), over all trials' bricks "
            "(means ± standard deviations):",
            "",
            *course_table(courses),
        ]
    if table.course_plot:
        lines += ["", f"![Errors per course]({COURSES_PLOT})"]
    return lines


def to_csv(table: Table) -> str:
    """One line per method and pattern (Average included): every Table I value, unrounded;
    then the Wilson interval of the success rate (fractions), each mean's bootstrap
    interval, and over all trials each mean (Average included), its standard deviation
    and its bootstrap interval."""
    metrics = [m for m, *_ in COLUMNS]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        [
            "method", "pattern", "successes", "trials", *(f"{m}_mean" for m in metrics),
            "success_ci_low", "success_ci_high",
            *(f"{m}_ci_{end}" for m in metrics for end in ("low", "high")),
            *(f"{m}_all_trials_{what}" for m in metrics for what in ("mean", "std")),
            *(f"{m}_all_trials_ci_{end}" for m in metrics for end in ("low", "high")),
        ]
    )  # fmt: skip
    for row in table.rows:
        for pattern in [*table.patterns, AVERAGE]:
            if (row, pattern) not in table.success:
                continue
            successful = table.means.stats.get((row, pattern), {})
            everything = table.all_means.stats.get((row, pattern), {})
            interval = table.success_interval(row, pattern)
            values = [
                *table.success[(row, pattern)],
                *(table.means.values[(row, pattern, m)] for m in metrics),
                *((None, None) if interval is None else (interval.low, interval.high)),
                *(v for m in metrics for v in _ci(successful.get(m))),
                *(
                    v
                    for m in metrics
                    for v in (table.all_means.values[(row, pattern, m)], _std(everything.get(m)))
                ),
                *(v for m in metrics for v in _ci(everything.get(m))),
            ]
            writer.writerow([row, pattern, *("" if v is None else repr(v) for v in values)])
    return buffer.getvalue()


def _ci(stats: MetricStats | None) -> tuple[float | None, float | None]:
    return (None, None) if stats is None else (stats.ci_low, stats.ci_high)


def _std(stats: MetricStats | None) -> float | None:
    return None if stats is None else stats.std


def _latex_escape(text: str) -> str:
    for char, escaped in (("\\", r"\textbackslash{}"), ("_", r"\_"), ("%", r"\%"), ("&", r"\&")):
        text = text.replace(char, escaped)
    for char in "#$":
        text = text.replace(char, "\\" + char)
    return text


def to_latex(table: Table) -> str:
    """Table I as a booktabs tabular, laid out like the paper's (best values in bold); then
    the same over all trials, and success."""
    lines = [*_latex_means(table.means), "", f"% {ALL_TRIALS_TITLE}"]
    lines += [*_latex_means(table.all_means), "", *_latex_success(table)]
    return "\n".join(lines) + "\n"


def _latex_means(means: Means) -> list[str]:
    """Table I's figures as a booktabs tabular."""
    groups = [*means.patterns, AVERAGE]
    n = len(COLUMNS)
    lines = [
        r"\begin{tabular}{l" + "c" * (n * len(groups)) + "}",
        r"\toprule",
        r"\multirow{2}{*}{\textbf{Method}}"
        + "".join(rf" & \multicolumn{{{n}}}{{c}}{{\textbf{{{_latex_escape(p)}}}}}" for p in groups)
        + r" \\",
        "".join(rf"\cmidrule(lr){{{2 + i * n}-{1 + (i + 1) * n}}}" for i in range(len(groups))),
        " & ".join(
            [""]
            + [
                rf"\textbf{{{title}}} $\{'downarrow' if lower else 'uparrow'}$"
                for _ in groups
                for _, title, _, _, lower in COLUMNS
            ]
        )
        + r" \\",
        r"\midrule",
    ]
    for row in means.rows:
        cells = [_latex_escape(row)]
        for pattern in groups:
            for metric, *_ in COLUMNS:
                text, best = means.cell(row, pattern, metric)
                text = "--" if text == "–" else text
                cells.append(rf"\textbf{{{text}}}" if best else text)
        lines.append(" & ".join(cells) + r" \\")
    return [*lines, r"\bottomrule", r"\end{tabular}"]


def _latex_success(table: Table) -> list[str]:
    """Success per pattern and over all, each with its Wilson 95 % interval, as a second
    tabular."""
    groups = [*table.patterns, AVERAGE]
    titles = [p if p != AVERAGE else "all" for p in groups]
    return [
        r"\begin{tabular}{l" + "c" * len(groups) + "}",
        r"\toprule",
        " & ".join(
            [r"\textbf{Method}", *(rf"\textbf{{{_latex_escape(t)}: success}}" for t in titles)]
        )
        + r" \\",
        r"\midrule",
        *(
            " & ".join(
                [
                    _latex_escape(row),
                    *(_latex_escape(table.success_cell(row, p)).replace("–", "--") for p in groups),
                ]
            )
            + r" \\"
            for row in table.rows
        ),
        r"\bottomrule",
        r"\end{tabular}",
    ]
