"""`eval --rerun`: a Rerun recording per trial, read back with the Rerun SDK's own reader,
that changes nothing in the trial, serial or from worker processes."""

from __future__ import annotations

import itertools
import json
import os
import re
import sys
from pathlib import Path
from typing import Any

import pytest
from conftest import assert_clean_error, cli, eval_lines
from rerun.chunk import RrdReader

from actionreasoning.recording.rerun_log import SAMPLE_S, TIMELINE
from actionreasoning.trial.rules import Method
from actionreasoning.world.tolerances import Tolerances

ONE_BRICK = {
    "name": "one",
    "brick_size": [0.2, 0.095, 0.06],
    "bricks": [{"position": [0.0, 0.0, 0.03], "yaw_deg": 0}],
}


@pytest.fixture
def one_brick(tmp_path: Path) -> Path:
    path = tmp_path / "one.json"
    path.write_text(json.dumps(ONE_BRICK))
    return path


def columns(path: Path, entity: str, component: str) -> list[tuple[float, Any]]:
    """(sim time in s, value) of every row of ``entity``'s ``component`` in the recording."""
    rows = []
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if chunk.entity_path == entity and component in batch.schema.names:
            times = [ns / 1e9 for ns in batch.column(TIMELINE).cast("int64").to_pylist()]
            rows += zip(times, batch.column(component).to_pylist(), strict=True)
    return sorted(rows, key=lambda row: row[0])


@pytest.mark.slow
def test_recording_holds_the_bricks_pose_and_the_gate_verdicts(
    tmp_path: Path, one_brick: Path
) -> None:
    result = json.loads(eval_lines(tmp_path / "run", one_brick, Method.AGENTS, rerun=True))
    rrd = tmp_path / "run" / "rerun" / "trial_000.rrd"

    centers = columns(rrd, "/world/bricks", "Boxes3D:centers")
    times = [t for t, _ in centers]
    assert len(centers) > 20 and times == sorted(times)
    steps = {round(b - a, 6) for a, b in itertools.pairwise(times)}
    assert SAMPLE_S in steps  # the fixed cadence, plus the stages in between
    assert centers[-1][1][0] == pytest.approx(
        result["bricks"][0]["final_position"], abs=1e-6
    )  # float32
    start = result["bricks"][0]["target_position"]
    assert abs(centers[0][1][0][0] - start[0]) > 0.1  # it started away from its target

    gates = [text[0] for _, text in columns(rrd, "/agents/gates", "TextLog:text")]
    assert any(
        g.startswith("#0 pre_grasp brick 0 attempt 1 sigma1_pre_grasp passed") for g in gates
    )
    lift = next(g for g in gates if "sigma4_lift" in g)
    v_th = Tolerances().v_th_mps
    assert re.search(rf"relative_speed_mps [0-9.e-]+ <= {v_th:.4g} \(pass\)", lift), lift
    assert columns(rrd, "/world/waypoint", "Points3D:positions")
    assert columns(rrd, "/slip/held_brick_mps", "Scalars:scalars")
    pads = columns(rrd, "/forces/pad_n", "Scalars:scalars")
    assert len(pads) == len(centers) and max(left for _, (left, _) in pads) > 20  # N, held
    offsets = columns(rrd, "/offset_cm/brick_0", "Scalars:scalars")
    assert offsets[-1][1][0] == pytest.approx(result["bricks"][0]["center_offset_cm"], abs=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("method", list(Method))
def test_recording_changes_no_result(tmp_path: Path, one_brick: Path, method: Method) -> None:
    plain = eval_lines(tmp_path / "a", one_brick, method, rerun=False)
    recorded = eval_lines(tmp_path / "b", one_brick, method, rerun=True)
    assert plain == recorded
    assert (tmp_path / "b" / "rerun" / "trial_000.rrd").stat().st_size > 10_000
    assert not (tmp_path / "a" / "rerun").exists()


@pytest.mark.slow
def test_recordings_come_back_from_worker_processes(tmp_path: Path, one_brick: Path) -> None:
    serial = eval_lines(tmp_path / "a", one_brick, Method.CLASSICAL, rerun=False, trials=2)
    parallel = eval_lines(
        tmp_path / "b", one_brick, Method.CLASSICAL, rerun=True, trials=2, workers=2
    )
    assert sorted(serial.splitlines()) == sorted(parallel.splitlines())
    for trial in ("trial_000", "trial_001"):
        rrd = tmp_path / "b" / "rerun" / f"{trial}.rrd"
        assert columns(rrd, "/world/bricks", "Boxes3D:centers")


def os_threads() -> int:
    """This process's threads, the SDK's native ones included (``threading`` sees none)."""
    return len(os.listdir("/proc/self/task"))


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
def test_recordings_leave_no_threads_behind(tmp_path: Path, one_brick: Path) -> None:
    before = os_threads()  # the SDK's own runtime threads start when it is imported
    eval_lines(tmp_path / "run", one_brick, Method.CLASSICAL, rerun=True, trials=3)
    assert os_threads() <= before  # a recording left behind kept two threads each
    for trial in ("trial_000", "trial_001", "trial_002"):
        rrd = tmp_path / "run" / "rerun" / f"{trial}.rrd"
        assert columns(rrd, "/world/bricks", "Boxes3D:centers")


def test_rerun_without_the_sdk_is_a_clean_error(
    tmp_path: Path, one_brick: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "rerun", None)  # import rerun raises ImportError
    out = tmp_path / "run"
    result = cli(
        "eval", "--method", "classical", "--pattern", str(one_brick), "--out", str(out), "--rerun"
    )
    assert_clean_error(result, "--rerun", "actionreasoning[rerun]")
    assert not (out / "results.jsonl").exists()
