"""What a trial's recordings are called inside its run directory, and how its video plays.

Free of the simulator, so the report reads recordings by these names without it.
"""

from __future__ import annotations

#: The videos' frames per simulated second, also their playback rate (real time).
VIDEO_FPS = 5
#: In a trial's snapshot folder: the sheet of its stages, the close-up of the build, and
#: the folder of its overview frames, in trial order.
STAGE_SHEET = "stages.png"
FINAL_BUILD = "final_build.png"
FRAMES_DIR = "frames"
