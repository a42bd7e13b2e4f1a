"""Eval runs: their directories, lock, jobs and resume, summaries and provenance."""
