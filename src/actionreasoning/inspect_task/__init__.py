"""The Inspect task ``actionreasoning/brick_stack`` (the ``inspect`` extra).

``inspect eval actionreasoning/brick_stack --model MODEL`` runs the gated trials of
``actionreasoning eval`` with Inspect's model as the agents' language model: one sample a
seeded trial, scored by its results line (docs/inspect.md). Inspect finds the task through
the package's ``inspect_ai`` entry point, ``_registry.py``.
"""
