"""A video of a trial (``eval --video``): overview frames on a fixed simulated-time cadence,
as an MP4.

Every ``FRAME_S`` (``1 / FPS``) simulated seconds the recorder reads where the arm's joints
and the bricks are (a :class:`ScenePose`, some 50 microseconds) and hands it, with the
frame's caption, to the film process (``recording/film.py``), which renders and encodes on
another core while the trial runs on. From the same reading it keeps the frame's row of
the trial's frame record (``recording/frame_record.py``: the joints and gripper measured and
commanded). The video plays in real time. Its caption: simulated
time; the agent at work (brick, attempt) or the stage last done; and the last gate verdict,
which stays until the next (a gate that judges a motion's outcome is decided at no
simulated time before the next agent answers). Filming only
reads the simulator, so a filmed trial gives the same results as one without (tests check
this).
"""

from __future__ import annotations

import contextlib
import os
import pickle
import subprocess
import sys
import tempfile
import threading
from collections import deque
from pathlib import Path
from queue import SimpleQueue
from typing import IO

import actionreasoning
from actionreasoning.agents.transcript import AgentCall
from actionreasoning.errors import EngineError
from actionreasoning.recording.film import Frame, Reel
from actionreasoning.recording.frame_record import FrameRecord, FrameSample
from actionreasoning.recording.names import VIDEO_FPS
from actionreasoning.sim.camera import overview
from actionreasoning.sim.replica import SceneLooks, ScenePose
from actionreasoning.sim.robot_model import ARM_JOINTS, FINGER_LEFT, FINGER_RIGHT
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.runner import TrialObserver
from actionreasoning.world.stages import StageEvent

#: Frames per simulated second, and the playback rate: videos play in real time.
FPS = VIDEO_FPS
#: Simulated time between two frames.
FRAME_S = 1.0 / FPS
WIDTH, HEIGHT = 320, 240


class FilmFailed(EngineError):
    """The film process could not make the video (a full temporary directory, say); the
    message is its reason, in one line. The trial itself is whole."""


class VideoRecorder(TrialObserver):
    """Films a trial through a film process; ``close()`` waits for it and gives the MP4,
    ``frame_record()`` the frame record of the frames filmed."""

    every_s = FRAME_S

    def __init__(self) -> None:
        self._queue: SimpleQueue[Reel | Frame | None] = SimpleQueue()
        self._film: subprocess.Popen[bytes] | None = None
        self._feeder: threading.Thread | None = None
        self._reader: threading.Thread | None = None
        self._said: deque[bytes] = deque(maxlen=8)  # the film process's last output lines
        self._path: Path | None = None
        self._doing = "settling"
        self._verdict = ""
        self._samples: list[FrameSample] = []

    def tick(self, scene: Scene) -> None:
        if self._film is None:
            self._start(Reel(SceneLooks.of(scene), overview(scene), WIDTH, HEIGHT, FPS))
        caption = (f"{scene.time_s:5.1f} s  {self._doing}", self._verdict)
        pose = ScenePose.of(scene)
        self._samples.append(sample_of(scene, pose))
        self._queue.put(Frame(pose, caption))

    def stage(self, scene: Scene, event: StageEvent) -> None:
        brick = event.brick
        self._doing = "final settle" if brick < 0 else f"brick {brick}: {event.stage} done"

    def call(self, scene: Scene, call: AgentCall) -> None:
        self._doing = doing_text(call)
        if call.gates:
            self._verdict = verdict_text(call)

    def _start(self, reel: Reel) -> None:
        handle, name = tempfile.mkstemp(suffix=".mp4")
        os.close(handle)
        self._path = Path(name)
        # The film process finds this very package, however this process found it.
        package_root = str(Path(actionreasoning.__file__).parents[1])
        paths = [package_root, *filter(None, [os.environ.get("PYTHONPATH")])]
        command = [sys.executable, "-m", "actionreasoning.recording.film", name]
        self._film = subprocess.Popen(
            command,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            env={**os.environ, "PYTHONPATH": os.pathsep.join(paths)},
        )
        assert self._film.stdin is not None
        self._queue.put(reel)
        self._feeder = threading.Thread(target=self._feed, args=(self._film.stdin,), daemon=True)
        self._feeder.start()
        assert self._film.stdout is not None
        self._reader = threading.Thread(target=self._read, args=(self._film.stdout,), daemon=True)
        self._reader.start()

    def _feed(self, pipe: IO[bytes]) -> None:
        """Send the queued reel and frames to the film process, until ``None``; if it died,
        ``close()`` says so."""
        with contextlib.suppress(BrokenPipeError), pipe:
            while True:
                item = self._queue.get()
                pickle.dump(item, pipe)
                if item is None:
                    return

    def _read(self, pipe: IO[bytes]) -> None:
        """Keep the film process's last output lines (its reason, if it fails), reading
        all of it so that it never waits on a full pipe."""
        with pipe:
            for line in pipe:
                if line.strip():
                    self._said.append(line)

    def close(self) -> bytes:
        """The MP4 (empty if no frame was filmed), once the film process has encoded every
        frame and checked it whole; the recorder is done. :class:`FilmFailed` if it could
        not."""
        if self._film is None or self._feeder is None or self._path is None:
            return b""
        try:
            self._queue.put(None)
            self._feeder.join()
            code = self._film.wait()
            if self._reader is not None:
                self._reader.join()
            if code != 0:
                said = self._said[-1].decode(errors="replace").strip() if self._said else ""
                raise FilmFailed(said or f"the film process failed (exit code {code})")
            try:
                return self._path.read_bytes()
            except OSError as error:
                raise FilmFailed(f"{self._path}: {error.strerror or error}") from error
        finally:
            self._path.unlink(missing_ok=True)

    def frame_record(self) -> bytes:
        """The frame record (NPZ) of the frames filmed so far; empty if none was."""
        return FrameRecord.of(self._samples).npz() if self._samples else b""


def sample_of(scene: Scene, pose: ScenePose) -> FrameSample:
    """The frame record's row of ``scene`` posed as ``pose`` (read from it just now): the
    arm's joints and the opening between its finger pads, and the controller's targets."""
    joints = pose.joints_rad
    return FrameSample(
        time_s=scene.time_s,
        joints_rad=joints[list(ARM_JOINTS)],
        gripper_m=float(joints[FINGER_LEFT] + joints[FINGER_RIGHT]),
        joint_targets_rad=scene.arm_targets.copy(),
        gripper_target_m=2.0 * scene.finger_target_m,
    )


def doing_text(call: AgentCall) -> str:
    """The agent at work, on which brick, at which attempt."""
    brick = "" if call.brick is None else f"brick {call.brick}: "
    attempt = f" (attempt {call.attempt})" if call.attempt > 1 else ""
    return f"{brick}{call.agent}{attempt}"


def verdict_text(call: AgentCall) -> str:
    """The last gate verdict of ``call``, with the checks that failed."""
    gate = call.gates[-1]
    if gate.passed:
        return f"{call.agent}: {gate.gate} passed"
    failed = ", ".join(check.name for check in gate.checks if not check.passed)
    return f"{call.agent}: {gate.gate} FAILED ({failed})"
