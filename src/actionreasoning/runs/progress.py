"""How a run shows its progress: a rich bar on a terminal, one plain line per trial elsewhere."""

from __future__ import annotations

from types import TracebackType

from rich.console import Console
from rich.markup import escape
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TaskID,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from actionreasoning.records import FailureCode
from actionreasoning.runs.markdown import plural
from actionreasoning.runs.printable import printable
from actionreasoning.trial.results import TrialResult

#: Failures whose detail a trial's line gives: those the finished build was judged by,
#: which name the bricks that broke the success rule.
DETAILED = (FailureCode.MISPLACED, FailureCode.NOT_AT_REST)


def trial_line(result: TrialResult) -> str:
    """One finished trial in words: its outcome (with the bricks that broke the success
    rule, where they did) and its means over the bricks."""
    m, failure = result.metrics, result.failure
    if failure is None:
        status = "ok"
    elif failure.reason in DETAILED:
        status = f"FAILED ({failure.reason}: {failure.detail})"
    else:
        status = f"FAILED ({failure.reason})"
    return (
        f"trial {result.trial}: {status}; mean {m.center_offset_cm:.3f} cm, "
        f"{m.rotation_error_deg:.3f} deg, IoU {m.iou:.3f}"
    )


class ConsoleProgress:
    """A run observer (see run.RunObserver) printing to ``console``; use it as a context."""

    def __init__(self, console: Console, title: str) -> None:
        self.console = console
        self.title = title
        self.successes = 0
        self.done = 0
        self.total = 0
        self._bar: Progress | None = None
        self._task: TaskID | None = None

    def __enter__(self) -> ConsoleProgress:
        if self.console.is_terminal:
            self._bar = Progress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[successes]} ok"),
                TimeElapsedColumn(),
                TextColumn("left"),
                TimeRemainingColumn(),
                console=self.console,
            )
            self._bar.__enter__()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        if self._bar is not None:
            self._bar.__exit__(kind, error, trace)

    def started(self, total: int, finished: list[TrialResult]) -> None:
        """Show the bar, counting trials finished by an earlier session as done."""
        self.total, self.done = total, len(finished)
        self.successes = sum(r.success for r in finished)
        if finished:
            self._say(
                f"resuming: {len(finished)} of {plural(total, 'trial')} already in results.jsonl "
                f"({self.successes} ok)"
            )
        if self._bar is not None:
            self._task = self._bar.add_task(
                escape(printable(self.title)),
                total=total,
                completed=len(finished),
                successes=self.successes,
            )

    def finished(self, result: TrialResult) -> None:
        """Count one trial and print its line."""
        self.done += 1
        self.successes += result.success
        if self._bar is None or self._task is None:
            self._say(f"[{self.done}/{self.total}, {self.successes} ok] {trial_line(result)}")
            return
        self._say(trial_line(result))
        self._bar.update(self._task, advance=1, successes=self.successes)

    def note(self, line: str) -> None:
        """Print a line about the run (not a trial's)."""
        self._say(line)

    def _say(self, line: str) -> None:
        line = printable(line)
        if self._bar is not None:
            self._bar.console.print(line, highlight=False, markup=False)
        else:
            print(line, flush=True)
