"""Feature statistics as LeRobot 0.4 keeps them (``lerobot/datasets/compute_stats.py``):
``min``, ``max``, ``mean``, ``std``, ``count`` and the quantiles ``q01`` to ``q99``, per
episode and over the dataset.

A vector feature's are per dimension (a scalar's have shape (1,)). An image's are per
channel, of pixel values scaled to [0, 1], shape (3, 1, 1), over some of the episode's
frames (as LeRobot samples them), each taken at every other pixel; its ``count`` is the
frames taken. Quantiles are exact where LeRobot estimates them from histograms. Dataset
statistics combine the episodes' as LeRobot's ``aggregate_stats`` does: means weighted
by count, the pooled variance, quantiles averaged by count.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

Stats = dict[str, np.ndarray]

QUANTILES = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}
#: Frames LeRobot takes of an episode for image statistics: all of up to MIN_SAMPLES, then
#: length ** SAMPLE_POWER of them, evenly spread, up to MAX_SAMPLES.
MIN_SAMPLES, MAX_SAMPLES, SAMPLE_POWER = 100, 10_000, 0.75
#: An image this wide or high (px) or more is taken at every n-th pixel, n making it about
#: DOWNSAMPLED_PX along its longer side.
DOWNSAMPLE_FROM_PX, DOWNSAMPLED_PX = 300, 150
LEVELS = 256


def vector_stats(values: np.ndarray) -> Stats:
    """The statistics of ``values`` ((n,) or (n, d)), per dimension."""
    array = values.reshape(len(values), -1).astype(np.float64)
    stats = {
        "min": array.min(axis=0),
        "max": array.max(axis=0),
        "mean": array.mean(axis=0),
        "std": array.std(axis=0),
        "count": np.array([len(array)]),
    }
    return stats | {key: np.quantile(array, q, axis=0) for key, q in QUANTILES.items()}


def sampled_frames(length: int) -> list[int]:
    """The frames of an episode of ``length`` frames whose images enter its statistics."""
    wanted = max(min(MIN_SAMPLES, length), min(int(length**SAMPLE_POWER), MAX_SAMPLES))
    return sorted(set(np.round(np.linspace(0, length - 1, wanted)).astype(int).tolist()))


class ImageStats:
    """Per-channel statistics of RGB images (uint8, height x width x 3), added one by one:
    a histogram of each channel's levels, so that every statistic is exact."""

    def __init__(self) -> None:
        self._counts = np.zeros((3, LEVELS), dtype=np.int64)
        self._images = 0

    def add(self, image: np.ndarray) -> None:
        height, width, _ = image.shape
        if max(height, width) >= DOWNSAMPLE_FROM_PX:
            step = max(height, width) // DOWNSAMPLED_PX
            image = image[::step, ::step]
        for channel in range(3):
            self._counts[channel] += np.bincount(image[..., channel].ravel(), minlength=LEVELS)
        self._images += 1

    def stats(self) -> Stats:
        """The statistics of the images added, in [0, 1], each of shape (3, 1, 1)."""
        levels = np.arange(LEVELS, dtype=np.float64) / (LEVELS - 1)
        totals = self._counts.sum(axis=1)
        mean = self._counts @ levels / totals
        variance = (self._counts * (levels - mean[:, None]) ** 2).sum(axis=1) / totals
        seen = self._counts > 0
        stats = {
            "min": np.array([levels[row].min() for row in seen]),
            "max": np.array([levels[row].max() for row in seen]),
            "mean": mean,
            "std": np.sqrt(variance),
        }
        stats |= {
            key: np.array([_quantile(row, q) for row in self._counts]) / (LEVELS - 1)
            for key, q in QUANTILES.items()
        }
        return {key: value.reshape(3, 1, 1) for key, value in stats.items()} | {
            "count": np.array([self._images])
        }


def _quantile(counts: np.ndarray, q: float) -> float:
    """The ``q`` quantile of the levels counted in ``counts``, as ``np.quantile`` (linear)
    gives it of the levels themselves."""
    cumulative = np.cumsum(counts)
    position = q * (cumulative[-1] - 1)
    low, high = np.floor(position), np.ceil(position)
    below, above = np.searchsorted(cumulative, [low, high], side="right")
    return float(below + (position - low) * (above - below))


def aggregate(episodes: Sequence[Stats]) -> Stats:
    """One feature's statistics over the episodes whose statistics are ``episodes``."""
    counts = np.array([stats["count"][0] for stats in episodes], dtype=np.float64)
    shape = (-1,) + (1,) * episodes[0]["mean"].ndim
    weights = (counts / counts.sum()).reshape(shape)

    def stacked(key: str) -> np.ndarray:
        return np.stack([stats[key] for stats in episodes])

    mean = (weights * stacked("mean")).sum(axis=0)
    spread = stacked("std") ** 2 + (stacked("mean") - mean) ** 2
    return {
        "min": stacked("min").min(axis=0),
        "max": stacked("max").max(axis=0),
        "mean": mean,
        "std": np.sqrt((weights * spread).sum(axis=0)),
        "count": np.array([int(counts.sum())]),
    } | {key: (weights * stacked(key)).sum(axis=0) for key in QUANTILES}


def as_lists(stats: Stats) -> dict[str, list[object]]:
    """``stats`` as JSON (and Parquet) lists."""
    return {key: value.tolist() for key, value in stats.items()}
