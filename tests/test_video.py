"""`eval --video`: a trial filmed on its simulated-time cadence, without changing the trial."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
from conftest import SMALL_PATTERN, assert_processes_end, children, cli, eval_lines

from actionreasoning.agents.transcript import AgentCall, CheckRecord, GateRecord
from actionreasoning.recording.video import FPS, doing_text, verdict_text
from actionreasoning.sim.camera import FixedCamera, overview, render
from actionreasoning.sim.replica import Replica, SceneLooks, ScenePose
from actionreasoning.sim.scene import Scene
from actionreasoning.trial.rules import Method
from actionreasoning.world.physics import PAPER


@pytest.fixture
def one_brick(tmp_path: Path) -> Path:
    path = tmp_path / "one.json"
    path.write_text(json.dumps({**SMALL_PATTERN, "bricks": SMALL_PATTERN["bricks"][:1]}))
    return path


def check_video(out: Path, line: str) -> None:
    """The trial's MP4 is named by its outcome, has a frame at the start and one per 1/FPS
    simulated seconds, and is not a still."""
    result = json.loads(line)
    outcome = "ok" if result["success"] else result["failure"]["reason"]
    path = out / "videos" / f"trial_{result['trial']:03d}_{outcome}.mp4"
    frames = list(iio.imiter(path, plugin="FFMPEG"))
    ticks_per_frame = round(1.0 / FPS / PAPER.time_step_s)
    assert len(frames) == 1 + result["sim_steps"] // ticks_per_frame
    assert frames[0].shape == (240, 320, 3)
    assert any(not np.array_equal(frames[0], frame) for frame in frames[1:])


@pytest.mark.parametrize(
    "method",
    [
        pytest.param(Method.CLASSICAL, marks=pytest.mark.slow),  # two whole trials each
        pytest.param(Method.AGENTS, marks=pytest.mark.slow),
        pytest.param(Method.SINGLE_AGENT, marks=pytest.mark.slow),
    ],
)
def test_a_filmed_trial_has_its_video_and_the_same_result(
    tmp_path: Path, one_brick: Path, method: Method
) -> None:
    plain = eval_lines(tmp_path / "plain", one_brick, method, video=False)
    filmed = eval_lines(tmp_path / "filmed", one_brick, method, video=True)
    assert plain == filmed
    assert not (tmp_path / "plain" / "videos").exists()
    check_video(tmp_path / "filmed", filmed)


@pytest.mark.slow
def test_videos_come_back_from_worker_processes(tmp_path: Path, one_brick: Path) -> None:
    lines = eval_lines(tmp_path, one_brick, Method.CLASSICAL, video=True, trials=2, workers=2)
    for line in lines.splitlines():
        check_video(tmp_path, line)
    assert len(list((tmp_path / "videos").glob("*.mp4"))) == 2


@pytest.mark.slow  # two whole trials
def test_the_report_shows_failed_trials_videos_first(tmp_path: Path, one_brick: Path) -> None:
    common = ["eval", "--method", "classical", "--pattern", str(one_brick), "--trials", "1"]
    common += ["--physics", "precise", "--video"]  # where the classical script succeeds
    assert cli(*common, "--out", str(tmp_path / "built")).returncode == 0
    cut = cli(*common, "--out", str(tmp_path / "cut"), "--max-steps", "1500")
    assert cut.returncode == 0, cut.stderr
    assert [p.name for p in (tmp_path / "cut" / "videos").iterdir()] == [
        "trial_000_step_budget.mp4"
    ]
    report = tmp_path / "report"
    made = cli("report", str(tmp_path / "built"), str(tmp_path / "cut"), "--out", str(report))
    assert made.returncode == 0, made.stderr
    page = (report / "report.html").read_text()
    sources = re.findall(r'<video [^>]*src="([^"]+)"', page)
    assert len(sources) == 2 and "max_steps_1500" in sources[0]  # the failed trial first
    assert "(step_budget)" in page.split(sources[1])[0]  # its caption, before the other video
    assert all((report / source).read_bytes()[4:8] == b"ftyp" for source in sources)


def test_the_film_shows_what_render_shows(scene: Scene) -> None:
    """A replica posed from the scene, laid over a ground rendered once, gives render's very
    pixels, as the scene moves."""
    view = overview(scene)
    camera, replica = FixedCamera(view, 160, 120), Replica(SceneLooks.of(scene))
    try:
        for _ in range(2):
            replica.show(ScenePose.of(scene))
            assert np.array_equal(camera.render(replica.client), render(scene, view, 160, 120))
            scene.set_arm_targets(scene.arm_targets + 0.3)
            scene.step(scene.ticks_for(0.5))
    finally:
        replica.close()


def test_a_caption_names_the_agent_the_gate_and_the_checks_that_failed() -> None:
    failed = CheckRecord(
        name="clearance_m", value=0.01, relation=">=", threshold=0.02, passed=False
    )
    passed = CheckRecord(name="reachable", value=1.0, relation=">=", threshold=1.0, passed=True)
    call = AgentCall(
        call=3, agent="descent", brick=0, target=0, attempt=2, prompt_chars=10, answer={},
        gates=[GateRecord(gate="sigma2_descent", passed=False, checks=[passed, failed])],
    )  # fmt: skip
    assert doing_text(call) == "brick 0: descent (attempt 2)"
    assert verdict_text(call) == "descent: sigma2_descent FAILED (clearance_m)"
    call.gates.append(GateRecord(gate="sigma2_descent", passed=True, checks=[passed]))
    assert verdict_text(call) == "descent: sigma2_descent passed"


@pytest.mark.slow  # a whole trial
def test_a_script_without_a_main_guard_films(tmp_path: Path, one_brick: Path) -> None:
    """The film process is no ``multiprocessing`` child: it does not import the script."""
    script = tmp_path / "film_it.py"
    script.write_text(
        "import sys\n"
        "from actionreasoning.runs.jobs import TrialJob, execute\n"
        "from actionreasoning.trial.rules import Method\n"
        "from actionreasoning.trial.runner import TrialSpec\n"
        "from actionreasoning.world.patterns import load_pattern\n"
        "from actionreasoning.world.scene_spec import SceneSpec\n"
        f"goal = load_pattern({str(one_brick)!r}, SceneSpec())\n"
        "spec = TrialSpec(Method.CLASSICAL, 'one', goal, run_seed=3, trial=0)\n"
        "video = execute(TrialJob(spec=spec, video=True)).video\n"
        "sys.stdout.write(video[4:8].decode())\n"
    )
    run = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert run.returncode == 0, run.stderr
    assert run.stdout == "ftyp"  # an MP4


@pytest.mark.slow
def test_the_film_process_ends_when_its_run_is_killed(tmp_path: Path, one_brick: Path) -> None:
    command = [sys.executable, "-m", "actionreasoning", "eval", "--method", "classical"]
    command += ["--pattern", str(one_brick), "--trials", "3", "--video"]
    temp = tmp_path / "temp"  # where the run's unfinished MP4 is
    temp.mkdir()
    process = subprocess.Popen(
        [*command, "--out", str(tmp_path / "run")],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "TMPDIR": str(temp)},
    )
    deadline = time.monotonic() + 120
    while not (films := {c for c in children(process.pid) if "recording.film" in cmdline(c)}):
        assert process.poll() is None and time.monotonic() < deadline, "no film process started"
        time.sleep(0.05)
    process.kill()
    process.wait()
    assert_processes_end(films, "film processes")
    assert list(temp.iterdir()) == []  # it took its unfinished MP4 with it


def cmdline(pid: int) -> str:
    """The command line of process ``pid`` (empty once it is gone)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""
