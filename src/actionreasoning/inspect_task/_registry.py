"""What the ``inspect_ai`` entry point loads: importing the task registers it with Inspect."""

from actionreasoning.inspect_task.task import brick_stack

__all__ = ["brick_stack"]
