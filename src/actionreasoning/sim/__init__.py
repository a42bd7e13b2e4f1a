"""PyBullet backend: the arm with its gripper, the bricks, stepping, IK, contacts and camera.

PyBullet prints its build time on import; it is silenced here so that the command line's
output holds only what the user asked for.
"""

import os
import sys


def _import_pybullet_quietly() -> None:
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import pybullet  # noqa: F401
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


_import_pybullet_quietly()
