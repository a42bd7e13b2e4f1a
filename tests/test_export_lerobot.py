"""`export lerobot`: a filmed run as a LeRobot v3.0 dataset, read back with Hugging Face
`datasets`, pyarrow and imageio; and the frame record `eval --video` keeps for it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import datasets
import imageio.v3 as iio
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest
from conftest import SMALL_PATTERN, assert_clean_error, cli
from test_run_dir import write_run

from actionreasoning.errors import ConfigError
from actionreasoning.export.lerobot import export_lerobot
from actionreasoning.export.stats import QUANTILES, ImageStats, aggregate, vector_stats
from actionreasoning.recording.frame_record import FrameRecord
from actionreasoning.recording.video import FPS, FRAME_S
from actionreasoning.sim.robot_model import FINGER_MAX_M, FINGER_MIN_M
from actionreasoning.world.physics import PRECISE

STATS = {"min", "max", "mean", "std", "count", *QUANTILES}
FILES = {
    "meta/info.json",
    "meta/stats.json",
    "meta/tasks.parquet",
    "meta/episodes/chunk-000/file-000.parquet",
    "data/chunk-000/file-000.parquet",
    "videos/observation.images.overview/chunk-000/file-000.mp4",
}
VIDEO = "videos/observation.images.overview"


def filmed_run(out: Path, pattern: Path, *options: str) -> list[dict[str, object]]:
    """A classical run of ``pattern`` under precise physics (where the script builds it),
    filmed; its results lines."""
    run = cli(
        *("eval", "--method", "classical", "--pattern", str(pattern), "--physics", "precise"),
        *("--video", "--out", str(out), *options),
    )
    assert run.returncode == 0, run.stderr
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def one_brick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("pattern") / "one.json"
    path.write_text(json.dumps({**SMALL_PATTERN, "bricks": SMALL_PATTERN["bricks"][:1]}))
    return path


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory, one_brick: Path) -> Path:
    """Two filmed trials of one brick."""
    out = tmp_path_factory.mktemp("run") / "run"
    filmed_run(out, one_brick, "--trials", "2")
    return out


@pytest.fixture(scope="module")
def dataset(tmp_path_factory: pytest.TempPathFactory, run: Path) -> Path:
    out = tmp_path_factory.mktemp("dataset") / "dataset"
    said: list[str] = []
    summary = export_lerobot(run, out, said.append)
    assert (summary.episodes, summary.successes, summary.tasks) == (
        2,
        2,
        ("Build the one pattern: 1 brick",),
    )
    assert said[0].startswith("episode 1/2: trial 0, ok, ") and len(said) == 2
    assert summary.describe() == (
        f"2 episodes (2 successful), {summary.frames} frames, 1 task: a LeRobot v3.0 dataset "
        f"in {out}/"
    )
    return out


def info(dataset: Path) -> dict[str, object]:
    return json.loads((dataset / "meta/info.json").read_text())


def episodes(dataset: Path) -> list[dict[str, object]]:
    return pq.read_table(dataset / "meta/episodes/chunk-000/file-000.parquet").to_pylist()


def frames(dataset: Path) -> datasets.Dataset:
    """The frames' table, as `datasets` reads it (its cache beside the dataset)."""
    files = str(dataset / "data/chunk-000/file-000.parquet")
    cache = str(dataset.parent / "datasets-cache")
    return datasets.load_dataset("parquet", data_files=files, split="train", cache_dir=cache)


@pytest.mark.slow  # two whole trials
def test_a_filmed_trial_keeps_a_record_of_every_frame(run: Path) -> None:
    ticks_per_frame = round(FRAME_S / PRECISE.time_step_s)
    for line in (run / "results.jsonl").read_text().splitlines():
        result = json.loads(line)
        record = FrameRecord.read(run / "frames" / f"trial_{result['trial']:03d}.npz")
        video = run / "videos" / f"trial_{result['trial']:03d}_ok.mp4"
        assert len(record) == 1 + result["sim_steps"] // ticks_per_frame
        assert len(record) == sum(1 for _ in iio.imiter(video, plugin="FFMPEG"))
        assert np.allclose(record.time_s, np.arange(len(record)) * FRAME_S)
        # The gripper is commanded shut on the brick and open again; its pads follow.
        assert record.gripper_target_m[0] == pytest.approx(2 * FINGER_MAX_M)
        assert record.gripper_target_m.min() == pytest.approx(2 * FINGER_MIN_M)
        assert record.gripper_m.min() < record.gripper_m[0] - 0.05
        # The arm moves, and at rest at the end it stands where it is commanded.
        assert np.ptp(record.joints_rad, axis=0).max() > 0.5
        assert np.abs(record.joints_rad[-1] - record.joint_targets_rad[-1]).max() < 1e-2


@pytest.mark.slow
def test_the_dataset_has_the_v3_files_and_info(dataset: Path) -> None:
    written = {str(p.relative_to(dataset)) for p in dataset.rglob("*") if p.is_file()}
    assert written == FILES
    meta = info(dataset)
    assert meta["codebase_version"] == "v3.0" and meta["robot_type"] == "kuka_iiwa"
    assert (meta["fps"], meta["total_episodes"], meta["total_tasks"]) == (FPS, 2, 1)
    assert meta["total_frames"] == sum(e["length"] for e in episodes(dataset))
    assert meta["splits"] == {"train": "0:2"}
    assert meta["data_path"] == "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
    assert meta["video_path"] == (
        "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
    )
    features = meta["features"]
    assert isinstance(features, dict)
    assert {name: (f["dtype"], f["shape"]) for name, f in features.items()} == {
        "observation.images.overview": ("video", [240, 320, 3]),
        "observation.state": ("float32", [8]),
        "action": ("float32", [8]),
        "timestamp": ("float32", [1]),
        "frame_index": ("int64", [1]),
        "episode_index": ("int64", [1]),
        "index": ("int64", [1]),
        "task_index": ("int64", [1]),
    }
    assert features["action"]["names"][-1] == "gripper.pos"


@pytest.mark.slow
def test_frames_read_back_with_datasets_in_their_episodes(dataset: Path) -> None:
    table = frames(dataset)
    state = table.features["observation.state"]
    assert (state.feature.dtype, state.length) == ("float32", 8)
    assert table.features["action"] == state
    assert table.features["timestamp"].dtype == "float32"
    for name in ("frame_index", "episode_index", "index", "task_index"):
        assert table.features[name].dtype == "int64"
    columns = table.with_format("numpy")[:]
    assert np.array_equal(columns["index"], np.arange(len(table)))
    assert np.allclose(columns["timestamp"], columns["frame_index"] / FPS)
    assert set(columns["task_index"]) == {0}
    for episode in episodes(dataset):
        rows = columns["episode_index"] == episode["episode_index"]
        start, end = episode["dataset_from_index"], episode["dataset_to_index"]
        assert rows.sum() == episode["length"] == end - start
        assert np.array_equal(columns["index"][rows], np.arange(start, end))
        assert np.array_equal(columns["frame_index"][rows], np.arange(episode["length"]))
        assert episode[f"{VIDEO}/from_timestamp"] == pytest.approx(start / FPS)
        assert episode[f"{VIDEO}/to_timestamp"] == pytest.approx(end / FPS)
        assert episode["tasks"] == ["Build the one pattern: 1 brick"]
        assert (episode["success"], episode["failure"]) == (True, None)
    tasks = pd.read_parquet(dataset / "meta/tasks.parquet")  # as LeRobot reads it
    assert tasks.loc["Build the one pattern: 1 brick", "task_index"] == 0


@pytest.mark.slow
def test_state_and_action_are_the_frame_records(run: Path, dataset: Path) -> None:
    columns = frames(dataset).with_format("numpy")[:]
    for episode in episodes(dataset):
        record = FrameRecord.read(run / "frames" / f"trial_{episode['trial']:03d}.npz")
        rows = columns["episode_index"] == episode["episode_index"]
        assert np.allclose(columns["observation.state"][rows][:, :7], record.joints_rad)
        assert np.allclose(columns["observation.state"][rows][:, 7], record.gripper_m)
        assert np.allclose(columns["action"][rows][:, :7], record.joint_targets_rad)
        assert np.allclose(columns["action"][rows][:, 7], record.gripper_target_m)


@pytest.mark.slow
def test_the_video_holds_every_episode_in_turn(run: Path, dataset: Path) -> None:
    video = list(iio.imiter(dataset / VIDEO / "chunk-000/file-000.mp4", plugin="FFMPEG"))
    assert len(video) == info(dataset)["total_frames"]
    assert video[0].shape == (240, 320, 3)
    for episode in episodes(dataset):
        source = run / "videos" / f"trial_{episode['trial']:03d}_ok.mp4"
        trial = list(iio.imiter(source, plugin="FFMPEG"))
        start = episode["dataset_from_index"]
        for k, frame in enumerate(trial):  # the same pictures, encoded again
            assert np.abs(video[start + k].astype(float) - frame).mean() < 3


@pytest.mark.slow
def test_stats_cover_every_feature_as_lerobot_keeps_them(dataset: Path) -> None:
    stats = json.loads((dataset / "meta/stats.json").read_text())
    features = info(dataset)["features"]
    assert isinstance(features, dict)
    assert set(stats) == set(features)
    assert all(set(feature) == STATS for feature in stats.values())
    columns = frames(dataset).with_format("numpy")[:]
    state = columns["observation.state"].astype(np.float64)
    assert stats["observation.state"]["count"] == [len(state)]
    assert np.allclose(stats["observation.state"]["mean"], state.mean(axis=0))
    assert np.allclose(stats["observation.state"]["std"], state.std(axis=0))
    assert np.allclose(stats["action"]["max"], columns["action"].max(axis=0))
    image = {key: np.array(value) for key, value in stats["observation.images.overview"].items()}
    assert image["mean"].shape == (3, 1, 1)
    assert 0 <= image["min"].min() < image["mean"].min() < image["max"].max() <= 1
    assert image["std"].min() > 0.05  # a picture, not a flat colour
    row = episodes(dataset)[0]
    assert {key.split("/")[1] for key in row if key.startswith("stats/")} == set(features)


@pytest.mark.slow  # a trial cut at 1500 steps
def test_a_failed_trial_is_an_episode_marked_failed(tmp_path: Path, one_brick: Path) -> None:
    filmed_run(tmp_path / "run", one_brick, "--trials", "1", "--max-steps", "1500")
    export_lerobot(tmp_path / "run", tmp_path / "dataset")
    [episode] = episodes(tmp_path / "dataset")
    assert (episode["success"], episode["failure"]) == (False, "step_budget")
    assert episode["length"] == 1 + 1500 // round(FRAME_S / PRECISE.time_step_s)


def test_a_run_without_videos_is_refused_with_what_to_do(tmp_path: Path) -> None:
    write_run(tmp_path / "run", 2)
    with pytest.raises(ConfigError, match=r"has no videos with frame records .* --video"):
        export_lerobot(tmp_path / "run", tmp_path / "dataset")
    assert not (tmp_path / "dataset").exists()
    with pytest.raises(ConfigError, match=r"has no results\.jsonl"):
        export_lerobot(tmp_path, tmp_path / "dataset")


@pytest.mark.slow
def test_a_trial_without_its_frame_record_is_named(tmp_path: Path, run: Path) -> None:
    shutil.copytree(run, tmp_path / "run")
    (tmp_path / "run" / "frames" / "trial_001.npz").unlink()
    with pytest.raises(ConfigError, match=r"lacks the video or frame record of trial 1 "):
        export_lerobot(tmp_path / "run", tmp_path / "dataset")


@pytest.mark.slow  # no trial: the resume finds both finished
def test_a_resume_names_a_missing_frame_record(tmp_path: Path, run: Path, one_brick: Path) -> None:
    shutil.copytree(run, tmp_path / "run")
    (tmp_path / "run" / "frames" / "trial_000.npz").unlink()
    again = cli(
        *("eval", "--method", "classical", "--pattern", str(one_brick), "--physics", "precise"),
        *("--video", "--out", str(tmp_path / "run"), "--trials", "2"),
    )
    assert again.returncode == 0, again.stderr
    assert f"missing from {tmp_path / 'run'}: frame record of trial 0," in again.stdout


@pytest.mark.slow
def test_a_record_that_is_not_its_videos_leaves_no_dataset(tmp_path: Path, run: Path) -> None:
    shutil.copytree(run, tmp_path / "run")
    path = tmp_path / "run" / "frames" / "trial_001.npz"
    record = FrameRecord.read(path)
    short = FrameRecord(**{name: values[:-1] for name, values in vars(record).items()})
    path.write_bytes(short.npz())
    with pytest.raises(ConfigError, match=r"trial_001_ok.mp4 has \d+ frames but its frame"):
        export_lerobot(tmp_path / "run", tmp_path / "dataset")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]  # nor a partial one


@pytest.mark.slow
def test_an_out_directory_in_use_is_refused(tmp_path: Path, run: Path) -> None:
    (tmp_path / "dataset").mkdir()
    (tmp_path / "dataset" / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="is not an empty directory"):
        export_lerobot(run, tmp_path / "dataset")
    assert [p.name for p in (tmp_path / "dataset").iterdir()] == ["notes.txt"]


@pytest.mark.parametrize(
    ("shape", "step"),
    [((4, 240, 320, 3), 2), ((2, 3, 5, 3), 1)],  # LeRobot takes every other pixel from 300 px
)
def test_image_stats_are_numpys(shape: tuple[int, ...], step: int) -> None:
    """Of the pixels LeRobot takes; a few pixels make quantiles fall between levels."""
    images = np.random.default_rng(0).integers(0, 256, size=shape, dtype=np.uint8)
    stats = ImageStats()
    for image in images:
        stats.add(image)
    found = stats.stats()
    pixels = images[:, ::step, ::step].reshape(-1, 3) / 255.0
    assert found["count"].tolist() == [len(images)]
    for key, expected in [
        ("mean", pixels.mean(axis=0)),
        ("std", pixels.std(axis=0)),
        ("min", pixels.min(axis=0)),
        *((key, np.quantile(pixels, q, axis=0)) for key, q in QUANTILES.items()),
    ]:
        assert found[key].shape == (3, 1, 1)
        assert np.allclose(found[key].ravel(), expected), key


def test_aggregated_stats_are_those_of_all_the_values() -> None:
    rng = np.random.default_rng(1)
    parts = [rng.normal(i, 1 + i, size=(20 + 10 * i, 8)) for i in range(3)]
    whole, combined = vector_stats(np.concatenate(parts)), aggregate(list(map(vector_stats, parts)))
    for key in ("min", "max", "mean", "std", "count"):
        assert np.allclose(combined[key], whole[key]), key


@pytest.mark.slow
def test_the_export_command_writes_the_dataset_in_one_line(tmp_path: Path, run: Path) -> None:
    written = cli("export", "lerobot", str(run), "--out", str(tmp_path / "dataset"))
    assert written.returncode == 0, written.stderr
    assert (tmp_path / "dataset" / "meta" / "info.json").is_file()
    last = written.stdout.strip().splitlines()[-1]
    assert last.endswith(f"a LeRobot v3.0 dataset in {tmp_path / 'dataset'}/"), last


def test_the_export_command_refuses_a_run_without_videos_in_one_line(tmp_path: Path) -> None:
    write_run(tmp_path / "run", 2)
    refused = cli("export", "lerobot", str(tmp_path / "run"), "--out", str(tmp_path / "d"))
    assert_clean_error(refused, "has no videos with frame records", "--video")
    refused = cli("export", "lerobot", str(tmp_path / "run"), "--out", "")
    assert_clean_error(refused, "--out: empty")
