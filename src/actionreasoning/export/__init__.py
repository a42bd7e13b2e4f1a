"""Eval runs in other tools' formats: LeRobot datasets of filmed runs (``lerobot.py``)."""
