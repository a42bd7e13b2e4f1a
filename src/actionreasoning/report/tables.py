"""The paper's Table I: methods in rows; per pattern and on average, rotation error (°),
centre offset (cm) and IoU (%), means over successful trials with their bootstrap
intervals; as markdown, CSV and LaTeX. Success comes with its Wilson interval; a method
that succeeded in no trial of a pattern gets its means over all trials instead, on a row of
their own. Then the leaderboard and the paired comparisons (McNemar's test). Rows and
pattern columns are the groups of collect.py; the notes say how runs differ. Runs with
answer errors get a table of what was corrupted and what caught it, runs with refused
answers a table per group of them by agent and error category, and runs whose checks refused
answers nobody corrupted a list of those checks. Every group gets its bricks placed before
the first failure and cycle time, and a table of its errors per course.
"""

from __future__ import annotations

import csv
import io
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from actionreasoning.agents.answer_errors import Caught
from actionreasoning.records import FailureClass, FailureCode
from actionreasoning.report.collect import Group, condition_notes, labels, patterns
from actionreasoning.report.ladder import LadderRow, ladder_lines, ladders
from actionreasoning.report.leaderboard import board_lines, board_rows
from actionreasoning.report.pairs import Pair, pair_lines, paired_comparisons
from actionreasoning.runs.courses import CourseMetrics
from actionreasoning.runs.markdown import captioned_table, table_lines
from actionreasoning.runs.statistics import BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, Interval, wilson
from actionreasoning.runs.summary import (
    CAUGHT_TITLES,
    AnswerErrorTotals,
    MetricStats,
    category_table,
    course_table,
    failure_classes,
    stats_text,
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
    f"{BOOTSTRAP_SEED}); {AVERAGE}: the mean over the patterns."
)
ALL_TRIALS_NOTE = (
    "No successful trial, so no figure in Table I: means ± standard deviations over all "
    "trials [bootstrap 95 % interval of the mean]."
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
    "Placed before the first failure",
    "Cycle time (simulated s / brick)",
    "Bricks an hour",
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
    """How far one method's trials on one pattern built within the success rule, and how
    fast: the bricks placed before the first brick out of the rule (a mean per trial, None
    where the rule is unknown), and simulated seconds per placed brick and bricks an hour
    (None where the physics is unknown or no brick was placed)."""

    label: str
    pattern: str
    bricks: int  # the pattern's
    before_failure: float | None
    seconds_per_brick: float | None
    bricks_per_hour: float | None

    @property
    def cells(self) -> list[str]:
        """The row as shown: PACE_COLUMNS."""
        before, seconds, hourly = self.before_failure, self.seconds_per_brick, self.bricks_per_hour
        return [
            self.label,
            self.pattern,
            "–" if before is None else f"{before:.2f} of {self.bricks}",
            "–" if seconds is None else f"{seconds:.1f}",
            "–" if hourly is None else f"{hourly:.0f}",
        ]


@dataclass(frozen=True)
class AllTrialsRow:
    """A method's means over all trials of a pattern it succeeded on in none (Table I has
    dashes there): labelled ``LABEL, all trials``."""

    label: str
    pattern: str
    stats: dict[str, MetricStats]  # metric -> over all trials
    successes: int
    trials: int

    @property
    def cells(self) -> list[str]:
        """The row as ALL_TRIALS_COLUMNS shows it: means ± standard deviations [intervals]."""
        return [
            f"{self.label}, all trials",
            self.pattern,
            *(
                stats_text(self.stats[metric], scale, digits)
                for metric, _, scale, digits, _ in COLUMNS
            ),
            success_text(self.successes, self.trials),
        ]


ALL_TRIALS_COLUMNS = (
    "Method",
    "Pattern",
    *(f"{title} {'↓' if lower else '↑'}" for _, title, _, _, lower in COLUMNS),
    "Success",
)


@dataclass(frozen=True)
class Table:
    """Cell values (None where a method has no successful trial on a pattern)."""

    rows: list[str]
    patterns: list[str]
    values: dict[tuple[str, str, str], float | None]  # (row, pattern or Average, metric)
    successful: dict[tuple[str, str], dict[str, MetricStats]]  # (row, pattern) -> metric ->
    # over successful trials, with the bootstrap interval of the mean where there are any
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
    all_stats: dict[tuple[str, str], dict[str, MetricStats]]  # (row, pattern) -> metric ->
    # over all trials
    board: list[list[str]]  # the leaderboard, a row per group (leaderboard.BOARD_COLUMNS)
    pairs: list[Pair]  # rows run on the same trials, compared
    ladder: list[LadderRow]  # the rungs of verification under each condition

    @property
    def all_trials(self) -> list[AllTrialsRow]:
        """A row of means over all trials for each method and pattern without a success."""
        return [
            AllTrialsRow(label, pattern, stats, *self.success[(label, pattern)])
            for (label, pattern), stats in self.all_stats.items()
            if not self.success[(label, pattern)][0]
        ]

    @property
    def course_plot(self) -> bool:
        """Whether a pattern has two courses or more, so that plots.course_errors draws."""
        return any(len(courses) > 1 for courses in self.courses.values())

    def best(self, pattern: str, metric: str) -> float | None:
        """The best value of a column, for bold type."""
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
        stats = self.successful.get((row, pattern), {}).get(metric)
        if stats is None or stats.ci_low is None or stats.ci_high is None:
            return ""
        _, _, scale, digits, _ = next(c for c in COLUMNS if c[0] == metric)
        return f"[{stats.ci_low * scale:.{digits}f}, {stats.ci_high * scale:.{digits}f}]"

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
    """Table I from grouped runs; Average is the mean over the patterns a method has values on."""
    rows, cols = labels(groups), patterns(groups)
    by_key = {(g.label, g.pattern): g for g in groups}
    values: dict[tuple[str, str, str], float | None] = {}
    success: dict[tuple[str, str], tuple[int, int]] = {}
    for row in rows:
        for metric, *_ in COLUMNS:
            means = []
            for pattern in cols:
                group = by_key.get((row, pattern))
                mean = None if group is None else group.summary.successful[metric].mean
                values[(row, pattern, metric)] = mean
                if mean is not None:
                    means.append(mean)
            values[(row, AVERAGE, metric)] = float(np.mean(means)) if means else None
        for pattern in cols:
            group = by_key.get((row, pattern))
            if group is not None:
                success[(row, pattern)] = (group.summary.successes, group.summary.trials)
        counts = [success[(row, p)] for p in cols if (row, p) in success]
        success[(row, AVERAGE)] = (sum(c[0] for c in counts), sum(c[1] for c in counts))
    return Table(
        rows=rows,
        patterns=cols,
        values=values,
        successful={(g.label, g.pattern): g.summary.successful for g in groups},
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
        all_stats={(g.label, g.pattern): g.summary.all_trials for g in groups},
        board=board_rows(groups),
        pairs=paired_comparisons(groups),
        ladder=ladders(groups),
    )


def _pace(group: Group) -> PaceRow:
    time = group.summary.cycle_time
    return PaceRow(
        label=group.label,
        pattern=group.pattern,
        bricks=group.summary.bricks_per_trial,
        before_failure=group.summary.placed_before_first_failure_mean,
        seconds_per_brick=None if time is None else time.seconds_per_brick,
        bricks_per_hour=None if time is None else time.bricks_per_hour,
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


def to_markdown(table: Table) -> str:
    """Table I as a markdown table (best of each column in bold), then success per pattern."""
    groups = [*table.patterns, AVERAGE]
    header = ["Method"] + [
        f"{p}: {title} {'↓' if lower else '↑'}" for p in groups for _, title, _, _, lower in COLUMNS
    ]
    lines = ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
    for row in table.rows:
        cells = [row]
        for pattern in groups:
            for metric, *_ in COLUMNS:
                text, best = table.cell(row, pattern, metric)
                interval = table.interval_cell(row, pattern, metric)
                cells.append(" ".join(filter(None, (f"**{text}**" if best else text, interval))))
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", MEANS_NOTE, ""]
    if table.all_trials:
        rows = [r.cells for r in table.all_trials]
        lines += [*captioned_table(ALL_TRIALS_NOTE, ALL_TRIALS_COLUMNS, rows), ""]
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
    lines = [
        "Bricks placed within the success rule before the first brick out of it (a mean per "
        "trial), and the cycle time: simulated seconds per placed brick, and the bricks an "
        "hour that makes:",
        "",
        *table_lines(PACE_COLUMNS, [row.cells for row in table.pace]),
    ]
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
    interval, and the means and standard deviations over all trials (patterns only)."""
    metrics = [m for m, *_ in COLUMNS]
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        [
            "method", "pattern", "successes", "trials", *(f"{m}_mean" for m in metrics),
            "success_ci_low", "success_ci_high",
            *(f"{m}_ci_{end}" for m in metrics for end in ("low", "high")),
            *(f"{m}_all_trials_{what}" for m in metrics for what in ("mean", "std")),
        ]
    )  # fmt: skip
    for row in table.rows:
        for pattern in [*table.patterns, AVERAGE]:
            if (row, pattern) not in table.success:
                continue
            successful = table.successful.get((row, pattern), {})
            everything = table.all_stats.get((row, pattern), {})
            interval = table.success_interval(row, pattern)
            values = [
                *table.success[(row, pattern)],
                *(table.values[(row, pattern, m)] for m in metrics),
                *((None, None) if interval is None else (interval.low, interval.high)),
                *(v for m in metrics for v in _ci(successful.get(m))),
                *(v for m in metrics for v in _mean_std(everything.get(m))),
            ]
            writer.writerow([row, pattern, *("" if v is None else repr(v) for v in values)])
    return buffer.getvalue()


def _ci(stats: MetricStats | None) -> tuple[float | None, float | None]:
    return (None, None) if stats is None else (stats.ci_low, stats.ci_high)


def _mean_std(stats: MetricStats | None) -> tuple[float | None, float | None]:
    return (None, None) if stats is None else (stats.mean, stats.std)


def _latex_escape(text: str) -> str:
    for char, escaped in (("\\", r"\textbackslash{}"), ("_", r"\_"), ("%", r"\%"), ("&", r"\&")):
        text = text.replace(char, escaped)
    for char in "#$":
        text = text.replace(char, "\\" + char)
    return text


def to_latex(table: Table) -> str:
    """Table I as a booktabs tabular, laid out like the paper's (best values in bold)."""
    groups = [*table.patterns, AVERAGE]
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
    for row in table.rows:
        cells = [_latex_escape(row)]
        for pattern in groups:
            for metric, *_ in COLUMNS:
                text, best = table.cell(row, pattern, metric)
                text = "--" if text == "–" else text
                cells.append(rf"\textbf{{{text}}}" if best else text)
        lines.append(" & ".join(cells) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}", "", *_latex_success(table)]
    return "\n".join(lines) + "\n"


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
