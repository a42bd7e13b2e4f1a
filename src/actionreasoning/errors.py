"""The project's one error family.

Every error a user can cause (bad files, bad options, unreachable targets) is an
:class:`ActionReasoningError`; the CLI prints its message on one line and exits non-zero.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from actionreasoning.records import FailureCode, LLMUsage

if TYPE_CHECKING:
    from actionreasoning.agents.error_kinds import ErrorCategory


class ActionReasoningError(Exception):
    """Base class of every error the project raises on purpose."""


class PatternError(ActionReasoningError):
    """A goal pattern (built-in or file) is malformed or physically impossible."""


class ConfigError(ActionReasoningError):
    """A command-line option or configuration value is invalid."""


class UnreachableError(ActionReasoningError):
    """The arm cannot reach a requested end-effector pose within tolerance."""


class ToolError(ActionReasoningError):
    """A tool was called with arguments that name nothing in the world (bad brick id, ...)."""


class TrialAborted(ActionReasoningError):
    """A trial stopped to stay safe or within its budget; ``reason`` is its failure code:
    ``safety_limit``, ``step_budget``, ``time_budget`` or ``physics_blowup``."""

    def __init__(self, reason: FailureCode, detail: str) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail


class EngineError(ActionReasoningError):
    """A worker process or Ray task running trials died; finished trials are kept."""


class StorageError(ActionReasoningError):
    """An output file could not be written (a full disk, a file size limit); the whole
    result lines written before are kept."""


class LLMError(ActionReasoningError):
    """A language model could not give a valid answer: the server failed or timed out, or
    every repair of its output was refused. ``reason`` is the trial's failure code;
    ``repairs`` why its outputs were sent back, ``repair_categories`` their categories."""

    def __init__(
        self,
        reason: FailureCode,
        detail: str,
        repairs: tuple[str, ...] = (),
        usage: LLMUsage | None = None,
        repair_categories: tuple[ErrorCategory, ...] = (),
    ) -> None:
        super().__init__(f"{reason}: {detail}")
        self.reason = reason
        self.detail = detail
        self.repairs = repairs
        self.usage = usage or LLMUsage()
        self.repair_categories = repair_categories
