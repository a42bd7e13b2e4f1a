"""Per-brick metrics against hand-computed values (brick 0.20 x 0.095 x 0.06 m)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from actionreasoning.trial.metrics import (
    box_iou,
    brick_metrics,
    center_offset_cm,
    rotation_error_deg,
    symmetric_rotation_error_deg,
)
from actionreasoning.world.boxes import Box

SIZE = (0.20, 0.095, 0.06)
VOLUME = 0.20 * 0.095 * 0.06
CENTRE = (0.4, -0.1, 0.03)
IDENTITY = (0.0, 0.0, 0.0, 1.0)
TARGET = Box(CENTRE, IDENTITY, SIZE)


def quat(rotation: Rotation) -> tuple[float, float, float, float]:
    return tuple(rotation.as_quat())


def rot_deg(axes: str, *angles: float) -> tuple[float, float, float, float]:
    return quat(Rotation.from_euler(axes, angles, degrees=True))


def shifted(offset: tuple[float, float, float]) -> tuple[float, float, float]:
    return tuple(np.add(CENTRE, offset))


def test_identical_boxes() -> None:
    q = rot_deg("zyx", 20, -10, 5)
    m = brick_metrics(Box(CENTRE, q, SIZE), Box(CENTRE, q, SIZE))
    assert m.iou == pytest.approx(1.0, abs=1e-9)
    assert m.center_offset_cm == 0.0
    assert m.rotation_error_deg == pytest.approx(0.0, abs=1e-5)
    assert m.symmetric_rotation_error_deg == pytest.approx(0.0, abs=1e-5)


def test_shift_along_long_axis() -> None:
    moved = shifted((0.01, 0.0, 0.0))
    assert box_iou(Box(moved, IDENTITY, SIZE), TARGET) == pytest.approx(0.19 / 0.21, abs=1e-9)
    assert center_offset_cm(moved, CENTRE) == pytest.approx(1.0, abs=1e-12)


def test_shift_in_3d_with_yawed_pose() -> None:
    yaw = Rotation.from_euler("z", 37, degrees=True)
    own_shift = (0.01, -0.02, 0.005)
    moved = shifted(tuple(yaw.apply(own_shift)))
    inter = (0.20 - 0.01) * (0.095 - 0.02) * (0.06 - 0.005)
    expected = inter / (2 * VOLUME - inter)
    assert box_iou(Box(moved, quat(yaw), SIZE), Box(CENTRE, quat(yaw), SIZE)) == pytest.approx(
        expected, abs=1e-9
    )
    assert center_offset_cm(moved, CENTRE) == pytest.approx(
        100 * math.sqrt(0.01**2 + 0.02**2 + 0.005**2), abs=1e-9
    )


def test_quarter_turn_about_z() -> None:
    q = rot_deg("z", 90)
    inter = 0.095 * 0.095 * 0.06
    m = brick_metrics(Box(CENTRE, q, SIZE), TARGET)
    assert m.iou == pytest.approx(inter / (2 * VOLUME - inter), abs=1e-9)
    assert m.rotation_error_deg == pytest.approx(90.0, abs=1e-9)
    assert m.symmetric_rotation_error_deg == pytest.approx(90.0, abs=1e-9)


def test_cube_turned_45_degrees_intersects_in_an_octagon() -> None:
    a = 0.1
    cube = (a, a, a)
    inter = 2 * (math.sqrt(2) - 1) * a**2 * a
    iou = box_iou(Box(CENTRE, rot_deg("z", 45), cube), Box(CENTRE, IDENTITY, cube))
    assert iou == pytest.approx(inter / (2 * a**3 - inter), abs=1e-9)


def test_disjoint_and_touching_boxes() -> None:
    assert box_iou(Box(shifted((0.3, 0.0, 0.0)), IDENTITY, SIZE), TARGET) == 0.0
    assert box_iou(Box(shifted((0.0, 0.0, 0.06)), IDENTITY, SIZE), TARGET) == 0.0
    yaw = Rotation.from_euler("z", 37, degrees=True)
    beside = shifted(tuple(yaw.apply((0.0, 0.095, 0.0))))
    assert box_iou(Box(beside, quat(yaw), SIZE), Box(CENTRE, quat(yaw), SIZE)) == pytest.approx(
        0.0, abs=1e-9
    )


@pytest.mark.parametrize("axis", ["x", "y", "z"])
def test_half_turns_are_symmetric(axis: str) -> None:
    q = rot_deg(axis, 180)
    assert rotation_error_deg(q, IDENTITY) == pytest.approx(180.0, abs=1e-9)
    assert symmetric_rotation_error_deg(q, IDENTITY) == pytest.approx(0.0, abs=1e-5)
    assert box_iou(Box(CENTRE, q, SIZE), TARGET) == pytest.approx(1.0, abs=1e-9)


def test_tilt_on_top_of_half_turn() -> None:
    target = rot_deg("z", 25)
    q = quat(Rotation.from_quat(target) * Rotation.from_euler("zx", [180, 2], degrees=True))
    assert symmetric_rotation_error_deg(q, target) == pytest.approx(2.0, abs=1e-6)
    assert rotation_error_deg(q, target) > 170.0


def test_rotation_about_arbitrary_axis() -> None:
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    target = Rotation.from_euler("xyz", [10, 20, 30], degrees=True)
    q = quat(Rotation.from_rotvec(math.radians(30) * axis) * target)
    assert rotation_error_deg(q, quat(target)) == pytest.approx(30.0, abs=1e-6)


def test_non_normalised_quaternions() -> None:
    q = rot_deg("zx", 90, 2)
    target = rot_deg("y", 10)
    moved = shifted((0.01, 0.0, 0.0))
    plain = brick_metrics(Box(moved, q, SIZE), Box(CENTRE, target, SIZE))
    scaled = brick_metrics(
        Box(moved, tuple(2 * np.array(q)), SIZE), Box(CENTRE, tuple(2 * np.array(target)), SIZE)
    )
    assert scaled.rotation_error_deg == pytest.approx(plain.rotation_error_deg, abs=1e-9)
    assert scaled.symmetric_rotation_error_deg == pytest.approx(
        plain.symmetric_rotation_error_deg, abs=1e-9
    )
    assert scaled.iou == pytest.approx(plain.iou, abs=1e-12)
    assert 0.0 < plain.iou < 1.0


def test_general_pose_matches_monte_carlo() -> None:
    rng = np.random.default_rng(0)
    q = rot_deg("zyx", 30, 15, -20)
    moved = shifted((0.03, 0.01, -0.01))
    iou = box_iou(Box(moved, q, SIZE), TARGET)
    half = np.array(SIZE) / 2
    points = rng.uniform(-half, half, size=(400_000, 3))  # in the target box's frame
    local = Rotation.from_quat(q).inv().apply(points + np.subtract(CENTRE, moved))
    inside = np.all(np.abs(local) <= half, axis=1).mean() * VOLUME
    assert iou == pytest.approx(inside / (2 * VOLUME - inside), abs=5e-3)
    assert box_iou(TARGET, Box(moved, q, SIZE)) == pytest.approx(iou, abs=1e-12)
