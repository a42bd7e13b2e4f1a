"""The LeRobot dataset format v3.0, as LeRobot 0.4 reads it (``lerobot/datasets/utils.py``):
where its files are, its features, and its ``meta/info.json``.

One chunk, one file each: LeRobot's file sizes (``*_files_size_in_mb``) only tell its own
writer when to start the next file; a reader follows the episodes' chunk and file indices.
"""

from __future__ import annotations

from typing import Any

CODEBASE_VERSION = "v3.0"
ROBOT_TYPE = "kuka_iiwa"
CHUNKS_SIZE = 1000
DATA_FILES_SIZE_IN_MB = 100
VIDEO_FILES_SIZE_IN_MB = 200

INFO_PATH = "meta/info.json"
STATS_PATH = "meta/stats.json"
TASKS_PATH = "meta/tasks.parquet"
CHUNK_FILE = "chunk-{chunk_index:03d}/file-{file_index:03d}"
EPISODES_PATH = "meta/episodes/" + CHUNK_FILE + ".parquet"
DATA_PATH = "data/" + CHUNK_FILE + ".parquet"
VIDEO_PATH = "videos/{video_key}/" + CHUNK_FILE + ".mp4"

IMAGE_KEY = "observation.images.overview"
STATE_KEY = "observation.state"
ACTION_KEY = "action"
#: The arm's joints A1..A7 (rad), then the opening between the finger pads (m): measured in
#: observation.state, commanded in action.
VECTOR_NAMES = [*(f"a{joint}.pos" for joint in range(1, 8)), "gripper.pos"]
#: Every frame's bookkeeping, as LeRobot names and types it (``DEFAULT_FEATURES``).
INDEX_FEATURES: dict[str, dict[str, Any]] = {
    "timestamp": {"dtype": "float32", "shape": [1], "names": None},
    "frame_index": {"dtype": "int64", "shape": [1], "names": None},
    "episode_index": {"dtype": "int64", "shape": [1], "names": None},
    "index": {"dtype": "int64", "shape": [1], "names": None},
    "task_index": {"dtype": "int64", "shape": [1], "names": None},
}
#: How the dataset's MP4 is encoded (``video/``), as ``get_video_info`` reads it back.
VIDEO_CODEC = "h264"
PIXEL_FORMAT = "yuv420p"


def path_of(template: str, video_key: str = IMAGE_KEY) -> str:
    """The dataset's one file of ``template`` (chunk 0, file 0)."""
    return template.format(video_key=video_key, chunk_index=0, file_index=0)


def features(height: int, width: int, fps: int) -> dict[str, dict[str, Any]]:
    """Every feature of a frame, with its dtype, shape and names: the overview video, the
    measured and the commanded joints and gripper, and the bookkeeping."""
    vector = {"dtype": "float32", "shape": [len(VECTOR_NAMES)], "names": VECTOR_NAMES}
    video_info = {
        "video.height": height,
        "video.width": width,
        "video.codec": VIDEO_CODEC,
        "video.pix_fmt": PIXEL_FORMAT,
        "video.is_depth_map": False,
        "video.fps": fps,
        "video.channels": 3,
        "has_audio": False,
    }
    return {
        IMAGE_KEY: {
            "dtype": "video",
            "shape": [height, width, 3],
            "names": ["height", "width", "channels"],
            "info": video_info,
        },
        STATE_KEY: vector,
        ACTION_KEY: vector,
        **INDEX_FEATURES,
    }


def info(
    features: dict[str, dict[str, Any]], fps: int, episodes: int, frames: int, tasks: int
) -> dict[str, Any]:
    """``meta/info.json``: the format, the robot, the totals, the paths and the features."""
    return {
        "codebase_version": CODEBASE_VERSION,
        "robot_type": ROBOT_TYPE,
        "total_episodes": episodes,
        "total_frames": frames,
        "total_tasks": tasks,
        "chunks_size": CHUNKS_SIZE,
        "data_files_size_in_mb": DATA_FILES_SIZE_IN_MB,
        "video_files_size_in_mb": VIDEO_FILES_SIZE_IN_MB,
        "fps": fps,
        "splits": {"train": f"0:{episodes}"},
        "data_path": DATA_PATH,
        "video_path": VIDEO_PATH,
        "features": features,
    }
