"""One writer per eval directory: an OS lock on its ``run.lock`` while a run writes there.

The lock is ``flock`` on the file, so the kernel drops it when its process ends, however it
ends: a killed run leaves nothing stale. Only the process that runs the trials holds it:
Python opens files non-inheritable, so worker processes (spawned) and Ray tasks do not.
While held, the file says who holds it; a second run is refused at once with that line.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from actionreasoning.errors import ConfigError
from actionreasoning.runs.layout import RunDir
from actionreasoning.runs.run_dir import output_directory, write_error

#: The directories (device, inode) this process holds.
_held: set[tuple[int, int]] = set()


@contextmanager
def run_lock(out: Path) -> Iterator[None]:
    """Hold ``out``'s lock for the block, creating ``out`` if new; refuse if another process
    holds it. Nested holds of one directory in one process share the lock."""
    created = not out.exists()
    key = _directory(out)
    if key in _held:  # held already, around this block (a demo around its run)
        yield
        return
    handle = _acquire(out)
    _held.add(key)
    try:
        yield
    finally:
        _held.discard(key)
        os.ftruncate(handle, 0)  # released: the file names nobody
        if created:
            _tidy(out)  # still locked: nobody else can be starting there
        os.close(handle)  # and the kernel drops the lock


def _tidy(out: Path) -> None:
    """Remove ``out``, made by this run, if nothing but its lock is left there: a run that
    failed to start leaves no directory behind."""
    lock = RunDir(out).lock
    try:
        if [entry.name for entry in out.iterdir()] == [lock.name]:
            lock.unlink()
            out.rmdir()
    except OSError:
        pass  # left as it is: a directory that cannot be tidied holds no result either


def _directory(out: Path) -> tuple[int, int]:
    """Create ``out`` if new; its (device, inode)."""
    output_directory(out)
    status = out.stat()
    return status.st_dev, status.st_ino


def _acquire(out: Path) -> int:
    """The open lock file of ``out``, locked by this process and naming it."""
    path = RunDir(out).lock
    try:
        handle = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as error:
        raise ConfigError(f"--out {out}: cannot write there ({error.strerror})") from error
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(handle, 512).decode(errors="replace").strip() or "just starting"
        os.close(handle)
        raise ConfigError(
            f"--out {out} is in use by another run ({holder}): wait for it to end, "
            "or choose another --out"
        ) from None
    except OSError as error:
        os.close(handle)
        raise ConfigError(f"--out {out}: cannot lock it ({error.strerror})") from error
    started = time.strftime("%Y-%m-%d %H:%M:%S %z")
    mark = f"pid {os.getpid()} on {socket.gethostname()} since {started}\n".encode()
    try:
        os.ftruncate(handle, 0)
        if os.write(handle, mark) != len(mark):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    except OSError as error:
        os.close(handle)
        raise write_error(path, error, "no trial has run yet") from error
    return handle
