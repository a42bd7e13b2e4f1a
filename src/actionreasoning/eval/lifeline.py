"""Child processes that end with their parent.

SIGKILL leaves a process no time to stop its children: a trial worker would finish its trial
for nobody, a film process would wait for frames forever. Each child watches its parent
instead and ends at once when it is gone.
"""

from __future__ import annotations

import os
import threading
import time

PARENT_POLL_S = 0.5


def exit_with_parent(parent: int) -> None:
    """In a child process: end this process as soon as process ``parent`` is gone."""

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, daemon=True).start()
