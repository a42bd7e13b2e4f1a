"""The project's one error family.

Every error a user can cause (bad files, bad options, unreachable targets) is an
:class:`ActionReasoningError`; the CLI prints its message on one line and exits non-zero.
"""


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
