"""Evaluation: trials, metrics, aggregation and reports."""
