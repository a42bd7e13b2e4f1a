"""The directory `demo` writes: a new or empty one, or one an earlier demo made.

A demo replaces its own files on every run, so it marks its directory
(``RunDir.DEMO_MARKER``) and writes nowhere else: a directory with anything else in it is
refused, untouched.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from actionreasoning.errors import ConfigError
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run_lock import run_lock
from actionreasoning.world.config_files import check_file_name

NOTE = (
    "Written by `actionreasoning demo`: a demo into this directory again replaces "
    f"{', '.join(RunDir.DEMO_FILES)} and the folders {' and '.join(RunDir.DEMO_FOLDERS)}.\n"
)


@contextmanager
def demo_directory(out: Path) -> Iterator[None]:
    """Hold ``out`` for a demo: refuse it, untouched, if it holds anything but an earlier
    demo; else lock it, remove the earlier demo's files and mark it."""
    _check(out)
    with run_lock(out):
        try:
            for name in RunDir.DEMO_FILES:
                (out / name).unlink(missing_ok=True)
            for folder in RunDir.DEMO_FOLDERS:
                shutil.rmtree(out / folder, ignore_errors=True)
            RunDir(out).demo_marker.write_text(NOTE)
        except OSError as error:
            raise ConfigError(
                f"--out {out}: cannot replace the earlier demo there ({error.strerror})"
            ) from error
        yield


def _check(out: Path) -> None:
    """Refuse a directory that is neither new, nor empty, nor an earlier demo's."""
    check_file_name(out, "--out")
    if not out.exists():
        return
    if not out.is_dir():
        raise ConfigError(f"--out {out} exists and is not a directory")
    try:
        names = {path.name for path in out.iterdir()}
    except OSError as error:
        raise ConfigError(f"--out {out}: cannot read it ({error.strerror})") from error
    if names and RunDir.DEMO_MARKER not in names:
        raise ConfigError(
            f"--out {out} is not empty and not an earlier demo's directory "
            f"(no {RunDir.DEMO_MARKER}): "
            "demo writes only into a new or empty directory, or its own; choose another --out"
        )
