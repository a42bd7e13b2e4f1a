"""The `actionreasoning` command.

Each command imports what it runs when it runs, so ``--help``, ``report`` and ``pattern``
load neither the simulator nor a model client.
"""

from __future__ import annotations

import math
import os
import signal
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from actionreasoning import __version__
from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.tiers import DEFAULT_TIER, TIER_HELP, ToolTier
from actionreasoning.agents.verification import Verification
from actionreasoning.errors import ActionReasoningError, ConfigError
from actionreasoning.reasoners.registry import backend_help
from actionreasoning.reasoners.sampling import MAX_COMPLETION_TOKENS, Effort, Sampling
from actionreasoning.recording.names import VIDEO_FPS
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.paper import TRIALS as PAPER_TRIALS
from actionreasoning.runs.printable import printable
from actionreasoning.trial.rules import Method, check_observation, check_rung, rung_of
from actionreasoning.world.budget import TrialBudget
from actionreasoning.world.config_files import check_file_name
from actionreasoning.world.geometry import quat_yaw
from actionreasoning.world.models import Supply
from actionreasoning.world.patterns import load_pattern, save_pattern
from actionreasoning.world.scenarios import NOISE, PATTERNS, PHYSICS, load_noise
from actionreasoning.world.scene_spec import SceneSpec
from actionreasoning.world.tolerances import Tolerances
from actionreasoning.world.walls import Bond, wall_pattern

if TYPE_CHECKING:
    from actionreasoning.reasoners.backend import LLMConfig
    from actionreasoning.report.tables import Table as ComparisonTable
    from actionreasoning.runs.run import RunConfig
    from actionreasoning.runs.summary import RunSummary
    from actionreasoning.trial.session import Conditions

app = typer.Typer(
    no_args_is_help=True,
    pretty_exceptions_enable=False,
)
console = Console()
err_console = Console(stderr=True)


def _print_version(given: bool) -> None:
    if given:
        console.print(f"actionreasoning {__version__}", highlight=False)
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool,
        typer.Option(
            "--version",
            callback=_print_version,
            is_eager=True,
            help="Print the version and exit.",
        ),
    ] = False,
) -> None:
    """LLM action reasoning for robot brick stacking: simulate, evaluate, report."""


BUILTIN_PATTERNS = ", ".join(f"'{name}'" for name in PATTERNS)
PatternOption = Annotated[
    str,
    typer.Option(help=f"{BUILTIN_PATTERNS}, or a pattern file (JSON/YAML, see docs/patterns.md)."),
]
LLMOption = Annotated[str, typer.Option(help=backend_help())]
BaseUrlOption = Annotated[
    str | None,
    typer.Option(help="Base URL of an OpenAI-compatible server (default: OPENAI_BASE_URL)."),
]
PhysicsOption = Annotated[
    str,
    typer.Option(
        help="Physics profile: "
        + ", ".join(f"'{entry.name}' ({entry.help})" for entry in PHYSICS.entries)
        + " or a profile file (JSON/YAML, see docs/conditions.md)."
    ),
]
NoiseOption = Annotated[
    str,
    typer.Option(
        help=f"Perturbations drawn from each trial's seed: {', '.join(NOISE)} (perception "
        "noise and per-brick friction, mass and size; see docs/conditions.md) or a noise file."
    ),
]

ToolsOption = Annotated[
    ToolTier,
    typer.Option(
        help="Reasoning tier, the tools the agents get: "
        + "; ".join(f"{tier}: {text}" for tier, text in TIER_HELP.items())
        + ". Figures of different tiers are never pooled."
    ),
]


def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise typer.BadParameter(f"{value} is not a finite number of seconds")
    return value


TimeoutOption = Annotated[
    float,
    typer.Option(
        min=0.1,
        callback=_finite,
        help="Seconds one request to the model server may take in all: connect, wait and "
        "read (each retry gets as long again).",
    ),
]
SeedOption = Annotated[
    int, typer.Option(min=0, help="Run seed; trial k uses a seed from (seed, k).")
]
TemperatureOption = Annotated[
    float, typer.Option(help="Sampling temperature of the model, 0 (greedy) to 2.")
]
TopPOption = Annotated[
    float | None,
    typer.Option(
        help="Nucleus sampling: the probability mass of the likeliest tokens sampled from, "
        "above 0 and at most 1 (default: not sent)."
    ),
]
MaxTokensOption = Annotated[
    int,
    typer.Option(
        help="Tokens a model's answer may take (with --reasoning-effort: its reasoning too)."
    ),
]
LLMSeedOption = Annotated[
    int, typer.Option(help="Sampling seed sent with every request, for servers that take one.")
]
EffortOption = Annotated[
    Effort | None,
    typer.Option(
        help="How hard a reasoning model thinks: the OpenAI API's reasoning_effort (default: "
        "not sent); for --llm openai:MODEL."
    ),
]


class Fallback(StrEnum):
    """Who answers a step after the model's repair budget is spent."""

    NONE = "none"
    BUILTIN = "builtin"


def _shown(text: str) -> str:
    """``text`` (a name, a path, a message quoting them) for rich markup: its control
    characters escaped (:func:`printable`), its [brackets] too."""
    return escape(printable(text))


def _say(line: str) -> None:
    """Print ``line`` as it is, but for its control characters (:func:`printable`)."""
    console.print(printable(line), highlight=False, markup=False, soft_wrap=True)


def _fail(error: ActionReasoningError | OSError, where: Path | None = None) -> None:
    """End the command with one line naming the problem (for a file error: the file, else
    ``where``)."""
    text = str(error)
    if isinstance(error, OSError) and (error.filename or where) is not None:
        text = f"{error.filename or where}: {error.strerror}"
    err_console.print(f"[bold red]error:[/] {_shown(text)}", highlight=False, soft_wrap=True)
    raise typer.Exit(code=2)


def _check_options(
    method: Method,
    llm: LLMConfig,
    transcripts: bool,
    answer_errors: float,
    persistence: float = 0.0,
    kinds: str = "all",
) -> None:
    if transcripts and method is Method.CLASSICAL:
        raise ConfigError("--transcripts records agent calls; --method classical makes none")
    for option, value in (
        ("--answer-errors", answer_errors),
        ("--answer-error-persistence", persistence),
    ):
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise ConfigError(f"{option} {value}: give a probability from 0 to 1")
    if answer_errors > 0 and method is Method.CLASSICAL:
        raise ConfigError("--method classical asks no reasoner; drop --answer-errors")
    if answer_errors == 0:
        given = [
            option
            for option, set_ in (
                ("--answer-error-persistence", persistence > 0),
                ("--answer-error-kinds", kinds.strip() != "all"),
            )
            if set_
        ]
        if given:
            raise ConfigError(
                f"{' and '.join(given)} shape the errors of --answer-errors, which is 0: give "
                f"--answer-errors a rate above 0, or drop {' and '.join(given)}"
            )
    if method is Method.CLASSICAL:
        given = (["--llm"] if llm.spec != "builtin" else []) + llm.sampling.options()
        if given:
            raise ConfigError(f"--method classical uses no reasoner; drop {', '.join(given)}")


def _summary_table(summary: RunSummary) -> Table:
    from actionreasoning.runs.summary import success_text

    s = summary.successful
    table = Table(
        title=_shown(f"{summary.method} on {summary.pattern}"),
        caption="means ± std over successful trials",
    )
    for column in ("Rot. Err (°)", "Ctr. Off. (cm)", "IoU (%)", "Success"):
        table.add_column(column, justify="right")

    def cell(metric: str, scale: float = 1.0) -> str:
        stats = s[metric]
        if stats.mean is None or stats.std is None:
            return "n/a"
        return f"{stats.mean * scale:.3f} ± {stats.std * scale:.3f}"

    table.add_row(
        cell("rotation_error_deg"),
        cell("center_offset_cm"),
        cell("iou", 100.0),
        success_text(summary.successes, summary.trials),
    )
    return table


OutOption = Annotated[
    str,
    typer.Option(
        metavar="DIR",
        help="Output directory. Created if new; if it holds this run already, the trials "
        "finished there are kept and only the missing ones run.",
    ),
]
MethodOption = Annotated[Method, typer.Option(help="Reasoning method.")]
TrialsOption = Annotated[int, typer.Option(min=1, help="Number of trials.")]
RecordOption = Annotated[
    str | None,
    typer.Option(
        metavar="FILE", help="Append every exchange with the model to this file, for replay:FILE."
    ),
]
FallbackOption = Annotated[
    Fallback, typer.Option(help="Who answers a step once the model's repair budget is spent.")
]
RetriesOption = Annotated[
    int, typer.Option(min=0, help="Retries on connection errors, 429 and 5xx (backoff).")
]
AnswerErrorsOption = Annotated[
    float,
    typer.Option(
        metavar="RATE",
        help="Corrupt each answer of the reasoner with this probability (0 to 1), drawn from "
        "the trial's seed, with a mistake models make (see docs/agents-and-gates.md): what "
        "the gates catch.",
    ),
]
VerifyOption = Annotated[
    Verification | None,
    typer.Option(
        help="The rung of verification, which verdicts refuse an answer (validation always): "
        "full (the gates and the pre-move checks), gates (sigma_1-sigma_6 only), checks "
        "(the pre-move checks only), none. Default: full for the agents, none for the "
        "single agent (the ablation ladder: docs/agents-and-gates.md).",
    ),
]
ObserveOption = Annotated[
    Observation,
    typer.Option(
        help="What the agents observe of the scene: state (the bricks' measured poses), "
        "image (no brick poses: with each call the cameras' pictures, overview in colour, "
        "top-down and pick-side in colour and depth, with the cameras' intrinsics and poses "
        "in the prompt; agent 1 names its brick by where it lies; tools check or none) or "
        "both (the poses and the pictures). Figures of different observations are never "
        "pooled.",
    ),
]
AnswerErrorPersistenceOption = Annotated[
    float,
    typer.Option(
        metavar="P",
        help="With --answer-errors: the probability (0 to 1) that the answer after a refused "
        "corrupted one repeats its mistake (the same kind on the same field), as a model "
        "holding a misconception does.",
    ),
]
AnswerErrorKindsOption = Annotated[
    str,
    typer.Option(
        metavar="KINDS",
        help="With --answer-errors: the kinds of mistake drawn from, comma-separated "
        "(sign_flip,near_offset,...; see docs/agents-and-gates.md), or 'all'.",
    ),
]
RepairsOption = Annotated[
    int, typer.Option(min=0, help="Invalid answers sent back to the model per step.")
]
ToolTurnsOption = Annotated[
    int, typer.Option(min=0, help="Rounds of tool calls a model may make per step.")
]
WorkersOption = Annotated[
    int, typer.Option(min=1, help="Trials in parallel, one worker process each.")
]
MaxStepsOption = Annotated[
    int,
    typer.Option(min=1, help="Simulation steps a trial may take (of the profile's time step)."),
]
MaxTrialSOption = Annotated[
    float, typer.Option(min=0.0, callback=_finite, help="Wall-clock seconds a trial may take.")
]
RayOption = Annotated[
    str | None,
    typer.Option(
        metavar="ADDRESS",
        help="Run trials as tasks on the Ray cluster at ADDRESS ('auto': the one started "
        "on this machine with `ray start`). Needs the ray extra.",
    ),
]
SnapshotsOption = Annotated[
    bool, typer.Option(help="Write per-stage PNG snapshots of every trial.")
]
TranscriptsOption = Annotated[
    bool,
    typer.Option(
        help="Write every agent call of trial k (prompt size, answer, tool calls, gate "
        "verdicts with measured values, retries) to transcripts/trial_k.jsonl."
    ),
]
RerunOption = Annotated[
    bool,
    typer.Option(
        help="Write a Rerun recording of trial k (the scene in 3D, every agent call and "
        "gate check, forces and slip, on the simulated timeline) to rerun/trial_k.rrd; "
        "open it with `rerun FILE`. Needs the rerun extra."
    ),
]
VideoOption = Annotated[
    bool,
    typer.Option(
        help=f"Film every trial from above, {VIDEO_FPS} frames per simulated second, to "
        "videos/trial_k_OUTCOME.mp4 (OUTCOME: ok or the failure code)."
    ),
]


@app.command("eval")
def eval_command(
    out: OutOption,
    method: MethodOption = Method.AGENTS,
    pattern: PatternOption = "pyramid",
    trials: TrialsOption = 10,
    seed: SeedOption = 0,
    llm: LLMOption = "builtin",
    physics: PhysicsOption = "paper",
    noise: NoiseOption = "none",
    tools: ToolsOption = DEFAULT_TIER,
    base_url: BaseUrlOption = None,
    record: RecordOption = None,
    fallback: FallbackOption = Fallback.NONE,
    llm_timeout: TimeoutOption = 60.0,
    llm_retries: RetriesOption = 2,
    temperature: TemperatureOption = 0.0,
    top_p: TopPOption = None,
    max_tokens: MaxTokensOption = MAX_COMPLETION_TOKENS,
    llm_seed: LLMSeedOption = 0,
    reasoning_effort: EffortOption = None,
    answer_errors: AnswerErrorsOption = 0.0,
    verify: VerifyOption = None,
    observe: ObserveOption = DEFAULT_OBSERVATION,
    answer_error_persistence: AnswerErrorPersistenceOption = 0.0,
    answer_error_kinds: AnswerErrorKindsOption = "all",
    repairs: RepairsOption = 2,
    tool_turns: ToolTurnsOption = 2,
    workers: WorkersOption = 1,
    max_steps: MaxStepsOption = TrialBudget().max_steps,
    max_trial_s: MaxTrialSOption = TrialBudget().max_wall_s,
    ray: RayOption = None,
    snapshots: SnapshotsOption = False,
    transcripts: TranscriptsOption = False,
    rerun: RerunOption = False,
    video: VideoOption = False,
) -> None:
    """Run randomized trials of one method on one pattern and write results and summaries.

    Trial k uses a seed from (--seed, k) only, so results are the same serial, with
    --workers or on Ray. Run the same command again to resume a killed run. The API key of
    an OpenAI-compatible server comes from OPENAI_API_KEY only, extra headers (a JSON
    object) from ACTIONREASONING_LLM_HEADERS.
    """
    from actionreasoning.agents.answer_errors import AnswerErrors, parse_kinds
    from actionreasoning.reasoners.backend import LLMConfig, ServerOptions
    from actionreasoning.reasoners.llm import LLMLimits
    from actionreasoning.trial.session import Conditions

    try:
        out_dir = _path(out, "--out")
        record_file = None if record is None else _path(record, "--record")
        backend = LLMConfig(
            spec=llm,
            server=ServerOptions(base_url=base_url, timeout_s=llm_timeout, max_retries=llm_retries),
            limits=LLMLimits(tool_turns=tool_turns, repairs=repairs),
            fallback=fallback is Fallback.BUILTIN,
            record=record_file,
            sampling=Sampling(temperature, top_p, max_tokens, llm_seed, reasoning_effort),
        )
        _check_options(
            method,
            backend,
            transcripts,
            answer_errors,
            answer_error_persistence,
            answer_error_kinds,
        )
        if method is Method.CLASSICAL and tools != DEFAULT_TIER:
            raise ConfigError("--method classical gives no agent tools; drop --tools")
        check_observation(method, observe)
        check_rung(method, verify)
        budget = TrialBudget(max_steps=max_steps, max_wall_s=max_trial_s)
        errors = AnswerErrors(
            # -0 is 0: one condition, one configuration hash.
            rate=answer_errors + 0.0,
            kinds=parse_kinds(answer_error_kinds),
            persistence=answer_error_persistence + 0.0,
        )
        conditions = Conditions.load(
            pattern,
            physics,
            noise,
            budget,
            tools,
            llm=backend,
            answer_errors=errors,
            # The method's own rung is recorded as none given: one run, however it is spelled.
            verify=None if verify == rung_of(method, None) else verify,
            observe=observe,
        )
        if method is not Method.CLASSICAL:
            Tolerances.derive().for_goal(conditions.goal)  # joints the gates can work with
    except ActionReasoningError as error:
        _fail(error)
    _evaluate(
        method,
        conditions,
        trials,
        seed,
        out_dir,
        snapshots=snapshots,
        transcripts=transcripts,
        rerun=rerun,
        video=video,
        workers=workers,
        ray=ray,
    )


@app.command()
def demo(
    out: Annotated[
        str,
        typer.Option(
            metavar="DIR", help="Output directory: new, empty, or one an earlier demo wrote."
        ),
    ] = "demo",
    pattern: PatternOption = "pyramid",
    seed: Annotated[int, typer.Option(min=0, help="Seed of the demo trial.")] = 0,
    physics: PhysicsOption = "paper",
    noise: NoiseOption = "none",
    tools: ToolsOption = DEFAULT_TIER,
) -> None:
    """Build a pattern once with the six agents and write a report with pictures of every stage.

    report.md shows the stages and the result; report/report.html adds the plots and an
    animation of the build. It writes only into a new or empty directory, which it marks as
    its own (.actionreasoning-demo), or into an earlier demo's, whose files it replaces.
    """
    from actionreasoning.report.demo import write_demo_pages
    from actionreasoning.runs.demo_dir import demo_directory
    from actionreasoning.trial.session import Conditions

    try:
        out_dir = _path(out, "--out")
        with demo_directory(out_dir):
            conditions = Conditions.load(pattern, physics, noise, tools=tools)
            _evaluate(Method.AGENTS, conditions, 1, seed, out_dir, snapshots=True, video=True)
            pages = write_demo_pages(RunDir(out_dir))
            _say(f"report: {pages.markdown} and {pages.html}")
    except ActionReasoningError as error:
        _fail(error)


def _evaluate(
    method: Method,
    conditions: Conditions,
    trials: int,
    seed: int,
    out: Path,
    *,
    snapshots: bool,
    transcripts: bool = False,
    rerun: bool = False,
    video: bool = False,
    workers: int = 1,
    ray: str | None = None,
) -> RunSummary:
    """Run the trials under ``conditions`` with progress, print the table; errors end the
    command."""
    from actionreasoning.runs.jobs import RESUME_HINT
    from actionreasoning.runs.progress import ConsoleProgress
    from actionreasoning.runs.run import RunConfig, run_eval
    from actionreasoning.runs.summary import wall_time_text

    run = RunConfig(
        method=method,
        pattern_name=conditions.pattern_name,
        goal=conditions.goal,
        trials=trials,
        seed=seed,
        out=out,
        config=conditions.config,
        snapshots=snapshots,
        transcripts=transcripts,
        rerun=rerun,
        video=video,
        workers=workers,
        ray=ray,
    )
    try:
        with _sigterm_as_ctrl_c(), ConsoleProgress(console, _title(run)) as progress:
            summary = run_eval(run, progress)
    except (ActionReasoningError, OSError) as error:
        _fail(error, out)
    except KeyboardInterrupt:
        err_console.print(f"interrupted: {RESUME_HINT}", highlight=False)
        raise typer.Exit(code=130) from None
    console.print(_summary_table(summary))
    _say(f"{wall_time_text(summary)}; results in {out}/")
    return summary


def _title(run: RunConfig) -> str:
    """The progress display's title: the method and what its trials run under."""
    config = run.config
    title = f"{run.method} / {run.pattern_name} / {config.physics.name} / noise {config.noise.name}"
    if run.method is not Method.CLASSICAL:
        title += f" / tools {config.tools}"
    if config.verify is not None:
        title += f" / verify {config.verify}"
    if config.observe.pictures:
        title += f" / observe {config.observe}"
    if config.answer_errors.rate:
        title += f" / answer errors {config.answer_errors.rate:g}"
    if config.answer_errors.persistence:
        title += f" (persistence {config.answer_errors.persistence:g})"
    return title


def _comparison(table: ComparisonTable) -> Table:
    """Table I for the terminal: one cell per pattern with its three means and successes
    (with the Wilson interval); a method with no success on a pattern gets a row of its
    means over all trials."""
    from actionreasoning.report.tables import AVERAGE, COLUMNS

    shown = Table(
        title="rotation error (°), centre offset (cm), IoU (%): means over successful trials",
        caption=f"details in table.md; {AVERAGE}: mean over the patterns; CI: Wilson 95 %",
    )
    shown.add_column("Method")
    columns = [*table.patterns, AVERAGE]
    for pattern in columns:
        shown.add_column(_shown(pattern), justify="right")
    everything = {(r.label, r.pattern): r for r in table.all_trials}
    for row in table.rows:
        cells = []
        for pattern in columns:
            values = [table.cell(row, pattern, metric) for metric, *_ in COLUMNS]
            text = " ".join(f"[bold]{v}[/]" if best else v for v, best in values)
            cells.append(f"{text}\n{_successes(table, row, pattern)}")
        shown.add_row(_shown(row), *cells)  # labels hold [brackets]
        if any((row, pattern) in everything for pattern in columns):
            means = {
                pattern: " ".join(
                    f"{(r.stats[metric].mean or 0.0) * scale:.{digits}f}"
                    for metric, _, scale, digits, _ in COLUMNS
                )
                for pattern in columns
                if (r := everything.get((row, pattern))) is not None
            }
            shown.add_row(_shown(f"{row}, all trials"), *(means.get(p, "") for p in columns))
    return shown


def _successes(table: ComparisonTable, row: str, pattern: str) -> str:
    """``17/20 ok, CI 64–95 %``, or a dash where the method did not run the pattern."""
    interval = table.success_interval(row, pattern)
    if interval is None:
        return "–"
    ok, trials = table.success[(row, pattern)]
    return f"{ok}/{trials} ok, CI {100 * interval.low:.0f}–{100 * interval.high:.0f} %"


def _cells_table(title: str, columns: Sequence[str], rows: Sequence[Sequence[str]]) -> Table:
    """A report's table of text cells for the terminal (table.md says what it is)."""
    shown = Table(title=title)
    for column in columns:
        shown.add_column(column)
    for row in rows:
        shown.add_row(*map(escape, row))
    return shown


@app.command("report")
def report_command(
    runs: Annotated[
        list[str],
        typer.Argument(
            metavar="RUN...", help="Eval --out directories: methods, backends, patterns."
        ),
    ],
    out: Annotated[
        str, typer.Option(metavar="DIR", help="Directory for the report's files.")
    ] = "report",
    gif: Annotated[
        bool, typer.Option(help="Also make an animated GIF of every trial with snapshots.")
    ] = False,
) -> None:
    """Compare eval runs: Table I (markdown, CSV, LaTeX), plots, stage grids, one HTML page.

    Runs are pooled only under the same run.json conditions (the seed aside) and pattern
    content; others are set side by side, and the report names the fields that differ.
    """
    try:
        out_dir = _path(out, "--out")
        run_dirs = [_path(run, "RUN") for run in runs]
    except ActionReasoningError as error:
        _fail(error)
    _report(run_dirs, out_dir, gif)


def _report(run_dirs: list[Path], out: Path, gif: bool = False, paper: bool = False) -> None:
    """Write the report of ``run_dirs`` into ``out`` and print its tables (with ``paper``,
    Table I beside the paper's too); errors end the command."""
    from actionreasoning.report.build import build_report
    from actionreasoning.report.ladder import LADDER_COLUMNS
    from actionreasoning.report.pairs import PAIR_COLUMNS
    from actionreasoning.runs.run_dir import check_output_path

    try:
        check_output_path(out)  # before reading the runs; created once they are read
        report = build_report(run_dirs, out, gifs=gif, paper=paper)
    except (ActionReasoningError, OSError) as error:
        _fail(error, out)
    console.print(_comparison(report.table))
    if paper:
        from actionreasoning.report.paper_rows import CAPTION, paper_rows

        console.print(_cells_table(CAPTION, *paper_rows(report.table)))
    if report.table.ladder:
        title = "the ablation ladder: rungs of verification under each condition"
        rows = [row.cells for row in report.table.ladder]
        console.print(_cells_table(title, LADDER_COLUMNS, rows))
    if report.table.pairs:
        title = "paired comparisons: McNemar's exact test on trials of the same seed"
        rows = [pair.cells for pair in report.table.pairs]
        console.print(_cells_table(title, PAIR_COLUMNS, rows))
    for note in report.table.notes:
        _say(note)
    if gif and not report.gifs:
        console.print("no GIFs: no run kept snapshots (eval --snapshots)", highlight=False)
    written = [*report.tables, *(p for p, _ in (*report.plots, *report.grids, *report.gifs))]
    _say(f"{len(written) + 1} files in {out}/; open {report.html}")


@app.command("paper")
def paper_command(
    out: OutOption,
    llm: LLMOption = "builtin",
    base_url: BaseUrlOption = None,
    llm_timeout: TimeoutOption = 60.0,
    trials: Annotated[
        int, typer.Option(min=1, help="Trials per method and pattern (the paper's: 10).")
    ] = PAPER_TRIALS,
    seed: SeedOption = 0,
    workers: WorkersOption = 1,
    snapshots: SnapshotsOption = False,
) -> None:
    """Run the paper's Table I protocol and report it beside the paper's figures.

    The six gated agents, the single agent and the classical script, each on pyramid and
    grid, --trials seeded trials under the paper's physics, into DIR/runs/METHOD-PATTERN as
    eval writes them; then the report into DIR/report, with paper.md: our Table I beside
    the paper's. Run it again to resume.
    """
    from actionreasoning.reasoners.backend import LLMConfig, ServerOptions
    from actionreasoning.runs.paper import paper_runs
    from actionreasoning.trial.session import Conditions

    try:
        out_dir = _path(out, "--out")
        backend = LLMConfig(
            spec=llm, server=ServerOptions(base_url=base_url, timeout_s=llm_timeout)
        )
        runs = paper_runs(out_dir)
        conditions = {
            (run.method, run.pattern): Conditions.load(
                run.pattern, llm=LLMConfig() if run.method is Method.CLASSICAL else backend
            )
            for run in runs
        }
    except ActionReasoningError as error:
        _fail(error)
    for run in runs:
        _evaluate(
            run.method,
            conditions[(run.method, run.pattern)],
            trials,
            seed,
            run.out,
            snapshots=snapshots,
            workers=workers,
        )
    _report([run.out for run in runs], out_dir / "report", paper=True)


@app.command("prompt")
def prompt_command(
    agent: Annotated[
        int,
        typer.Option(
            min=0, max=6, help="Agent number, 1 (pre-grasp) to 6; 0 is the merged single agent."
        ),
    ],
    pattern: PatternOption = "pyramid",
    seed: Annotated[int, typer.Option(min=0, help="Run seed; the scene is that of trial 0.")] = 0,
    physics: PhysicsOption = "paper",
    noise: NoiseOption = "none",
    tools: ToolsOption = DEFAULT_TIER,
    observe: ObserveOption = DEFAULT_OBSERVATION,
    pictures: Annotated[
        str | None,
        typer.Option(
            metavar="DIR",
            help="With --observe image or both: write the pictures the call carries into this "
            "directory, one PNG each named as the prompt names it (top_down.depth.png).",
        ),
    ] = None,
) -> None:
    """Print the prompt agent N is first sent in trial 0 (the built-in reasoner answers
    the agents before it), to read and tune it."""
    from actionreasoning.agents.spec import agent_specs, single_agent_spec
    from actionreasoning.trial.first_prompt import first_prompt
    from actionreasoning.trial.session import Conditions

    try:
        if pictures is not None and not observe.pictures:
            raise ConfigError("--pictures needs --observe image or both: a state call carries none")
        check_observation(Method.AGENTS if agent else Method.SINGLE_AGENT, observe)
        conditions = Conditions.load(pattern, physics, noise, tools=tools, observe=observe)
        trial = conditions.spec(seed, 0)
        spec = agent_specs(tools)[agent - 1] if agent else single_agent_spec(tools)
        prompt, carried = first_prompt(trial, spec.key)
        if pictures is not None:
            folder = _path(pictures, "--pictures")
            folder.mkdir(parents=True, exist_ok=True)
            for picture in carried:
                (folder / f"{picture.name}.png").write_bytes(picture.png)
    except ActionReasoningError as error:
        _fail(error)
    except OSError as error:
        _fail(ConfigError(f"--pictures {printable(str(pictures))}: {error.strerror}"))
    print(printable(prompt, lines=True), end="")


class Schema(StrEnum):
    """The records whose JSON Schema `schema` prints."""

    RESULTS = "results"
    SUMMARY = "summary"
    CONFIG = "config"


@app.command("schema")
def schema_command(
    records: Annotated[
        Schema,
        typer.Argument(
            help="results: a line of results.jsonl; summary: summary.json; config: the trial "
            "configuration, run.json's 'config'."
        ),
    ],
) -> None:
    """Print the JSON Schema of an eval directory's records, to check or load them elsewhere."""
    import json

    from pydantic import BaseModel

    from actionreasoning.runs.summary import RunSummary
    from actionreasoning.trial.config import TrialConfig
    from actionreasoning.trial.results import TrialResult, json_schema

    models: dict[Schema, type[BaseModel]] = {
        Schema.RESULTS: TrialResult,
        Schema.SUMMARY: RunSummary,
        Schema.CONFIG: TrialConfig,
    }
    print(json.dumps(json_schema(models[records]), indent=2))


@app.command("pattern")
def pattern_command(
    pattern: Annotated[
        str | None, typer.Argument(help=f"{BUILTIN_PATTERNS}, or a pattern file.")
    ] = None,
    wall: Annotated[
        float | None,
        typer.Option(
            metavar="LENGTH_M",
            help="Instead of PATTERN, generate a straight wall about this long (m; the full "
            "bricks that fit, with 10 mm joints) and write it to --out.",
        ),
    ] = None,
    courses: Annotated[int | None, typer.Option(help="The wall's courses (default: 3).")] = None,
    bond: Annotated[
        Bond | None,
        typer.Option(
            help="running: every second course shifted by half a brick, half bricks at its "
            "ends; stack: joints over joints (default: running)."
        ),
    ] = None,
    supply: Annotated[
        Supply | None,
        typer.Option(help="Where the wall's bricks wait to be picked (default: pallet)."),
    ] = None,
    out: Annotated[
        str | None,
        typer.Option(
            metavar="FILE", help="The wall's pattern file to write (.json, .yaml or .yml)."
        ),
    ] = None,
    force: Annotated[
        bool, typer.Option("--force", help="Overwrite --out if the file exists.")
    ] = False,
) -> None:
    """Validate a goal pattern and print its target poses in the world frame; or, with
    --wall, generate a wall, write it to --out if it is valid, and print it."""
    try:
        if wall is None:
            options = (
                ("--courses", courses),
                ("--bond", bond),
                ("--supply", supply),
                ("--out", out),
                ("--force", force or None),
            )
            given = [name for name, value in options if value is not None]
            if pattern is None:
                raise ConfigError("give a PATTERN (a built-in or a file) or --wall LENGTH_M")
            if given:
                raise ConfigError(f"{', '.join(given)} go with --wall, not with a PATTERN")
            goal = load_pattern(pattern, SceneSpec())
        else:
            if pattern is not None:
                raise ConfigError(f"give a PATTERN ('{pattern}') or --wall, not both")
            path = _new_file(out, force)
            generated = wall_pattern(
                wall,
                3 if courses is None else courses,
                bond or Bond.RUNNING,
                supply=supply or Supply.PALLET,
                name=path.stem,
            )
            goal = save_pattern(generated, path, SceneSpec())
        Tolerances.derive().for_goal(goal)  # joints the agents' gates can work with
    except ActionReasoningError as error:
        _fail(error)
    table = Table(title=_shown(f"pattern {goal.name}: {len(goal.targets)} bricks, valid"))
    for column in ("#", "x (m)", "y (m)", "z (m)", "yaw (deg)"):
        table.add_column(column, justify="right")
    for target in goal.targets:
        x, y, z = target.pose.position_m
        yaw = quat_yaw(target.pose.quat_xyzw)
        table.add_row(
            str(target.index), f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", f"{math.degrees(yaw):.1f}"
        )
    console.print(table)
    if out is not None:
        _say(f"wrote {out}")


def _path(text: str, option: str) -> Path:
    """The path ``option`` names; refused in one line if it is empty (not the current
    directory) or no file can have it (said by its length, not printed whole)."""
    check_file_name(text, option)
    return Path(text)


def _new_file(out: str | None, force: bool) -> Path:
    """The pattern file --out names, refused in one line if it is not given, names no file,
    or exists (unless ``force``)."""
    if out is None:
        raise ConfigError("--wall needs --out FILE, the pattern file to write")
    path = _path(out, "--out") if out.strip() else Path()
    if not out.strip() or out.endswith(os.sep) or path.is_dir() or not path.stem:
        raise ConfigError(f"--out {out!r} names no file: give the pattern file to write")
    if path.exists() and not force:
        raise ConfigError(f"--out {out!r} exists: give --force to overwrite it")
    return path


@app.command("tolerances")
def tolerances_command(
    pattern: PatternOption = "pyramid",
    noise: NoiseOption = "none",
) -> None:
    """Print every gate threshold as a Markdown table: its design value, its value when the
    pattern is built under the noise level, what it protects and how it is derived."""
    from actionreasoning.world.tolerances import derivation_table

    try:
        level = load_noise(noise)
        goal = load_pattern(pattern, SceneSpec())
        run = Tolerances.derive().for_goal(goal).under(level.sensing())
    except ActionReasoningError as error:
        _fail(error)
    table = derivation_table(run, f"{goal.name}, noise {level.name}")
    print(printable(table, lines=True), end="")


@app.command("serve-reference")
def serve_reference(
    port: Annotated[
        int, typer.Option(min=0, max=65535, help="TCP port to listen on; 0 picks a free one.")
    ],
    host: Annotated[
        str, typer.Option(help="Loopback address to listen on (127.0.0.1, ::1 or localhost).")
    ] = "127.0.0.1",
    verbose: Annotated[bool, typer.Option(help="Log one line per request to stderr.")] = False,
) -> None:
    """Serve the prompt-only reference model as an OpenAI-compatible chat server on loopback.

    The model answers every chat completion from the text of the messages alone, never from
    the simulator: it is the benchmark's reference row, a perfect reader of the agents'
    prompts. Point a run at it with --llm openai:reference --base-url URL. Its token counts
    are estimates. The first line printed is the base URL; Ctrl-C or SIGTERM stops it. A
    client silent for 10 s, or whose request takes over 30 s or 64 KiB of headers, is closed,
    at most 32 requests are handled at once (503 over that), and each dropped client is one
    line on stderr.
    """
    from actionreasoning.reasoners.reference_server import ReferenceServer

    try:
        server = ReferenceServer(host, port, verbose)
    except ActionReasoningError as error:
        _fail(error)
    try:
        with _sigterm_as_ctrl_c():
            print(f"serving the prompt-only reference model at {server.url}", flush=True)
            server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()


@contextmanager
def _sigterm_as_ctrl_c() -> Iterator[None]:
    """SIGTERM stops what runs inside as Ctrl-C does (a KeyboardInterrupt), so it ends
    cleanly: its worker processes stopped, its files closed."""

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@app.command("mcp")
def mcp_command() -> None:
    """Serve trials to an outside agent over the Model Context Protocol (stdio).

    An MCP client (Claude Code, Claude Desktop, inspect_ai, your own) starts this command
    and talks to it on stdin and stdout: start a trial, read the waiting agent's state,
    call its measurement tools, submit its answers (validated and gated as an LLM's are)
    and finish with the results line. Needs the MCP SDK, the package's extra `mcp`.
    """
    try:
        from actionreasoning.mcp_server import serve
    except ImportError as error:
        _fail(ConfigError(str(error)))
    try:
        serve()
    except KeyboardInterrupt:
        pass


export_app = typer.Typer(help="Eval runs in other tools' formats.", no_args_is_help=True)
app.add_typer(export_app, name="export")


@export_app.command("lerobot")
def export_lerobot_command(
    run: Annotated[
        str, typer.Argument(metavar="RUN", help="An eval --out directory, filmed (--video).")
    ],
    out: Annotated[str, typer.Option(metavar="DIR", help="The dataset's directory: new or empty.")],
) -> None:
    """Write a filmed run's trials as a LeRobot dataset (format v3.0), an episode each.

    A frame holds the overview camera's picture, the arm's joints and gripper as measured
    (observation.state) and as commanded (action), and the pattern's task; the episodes
    say which trials succeeded (docs/lerobot.md).
    """
    try:
        from actionreasoning.export.lerobot import export_lerobot  # needs the export extra

        written = export_lerobot(_path(run, "RUN"), _path(out, "--out"), _say)
    except ActionReasoningError as error:
        _fail(error)
    _say(written.describe())


llm_app = typer.Typer(help="Language-model backends.", no_args_is_help=True)
app.add_typer(llm_app, name="llm")


@llm_app.command("check")
def llm_check(
    llm: LLMOption,
    base_url: BaseUrlOption = None,
    llm_timeout: TimeoutOption = 60.0,
    temperature: TemperatureOption = 0.0,
    top_p: TopPOption = None,
    max_tokens: MaxTokensOption = MAX_COMPLETION_TOKENS,
    llm_seed: LLMSeedOption = 0,
    reasoning_effort: EffortOption = None,
) -> None:
    """Connect to a backend, send one schema-constrained request, and report what came back."""
    from actionreasoning.reasoners.backend import LLMConfig, ServerOptions
    from actionreasoning.reasoners.factory import check_backend

    try:
        server = ServerOptions(base_url=base_url, timeout_s=llm_timeout)
        sampling = Sampling(temperature, top_p, max_tokens, llm_seed, reasoning_effort)
        report = check_backend(LLMConfig(spec=llm, server=server, sampling=sampling))
    except ActionReasoningError as error:
        _fail(error)
    table = Table(title=f"llm check {_shown(report.label)}", show_header=False)
    for name, value in (
        ("model", report.model),
        ("structured output", report.mode),
        ("latency", f"{report.latency_s:.2f} s"),
        ("tokens", f"{report.prompt_tokens} prompt, {report.completion_tokens} completion"),
        ("answer", ("valid: " if report.valid else "INVALID: ") + report.detail),
    ):
        table.add_row(name, _shown(value))
    console.print(table)
    if not report.valid:
        raise typer.Exit(code=1)
