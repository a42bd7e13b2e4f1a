"""Shared fixtures: a real PyBullet scene (DIRECT mode) with the default layout."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from actionreasoning.eval.trial import READY_POSE
from actionreasoning.sim.kinematics import KinematicArm
from actionreasoning.sim.scene import Scene
from actionreasoning.world.layout import sample_pick_poses
from actionreasoning.world.scene_spec import SceneSpec


@pytest.fixture
def arm() -> Iterator[KinematicArm]:
    arm = KinematicArm()
    yield arm
    arm.close()


@pytest.fixture
def scene(arm: KinematicArm) -> Iterator[Scene]:
    spec = SceneSpec()
    ready = arm.solve(READY_POSE.position_m, READY_POSE.quat_xyzw).joints_rad
    scene = Scene(spec, sample_pick_poses(np.random.default_rng(7), 6, spec), ready)
    yield scene
    scene.close()
