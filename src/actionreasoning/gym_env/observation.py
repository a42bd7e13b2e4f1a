"""The environment's spaces: the measured world state as arrays plus its JSON text, and an
action as JSON text."""

from __future__ import annotations

import json
import string
from typing import Any

import numpy as np
from gymnasium import spaces

from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.validation import MAX_ANSWER_CHARS
from actionreasoning.world.models import BrickStatus, Pose, WorldState

#: The agents in pipeline order; the observation's ``agent`` is an index into it, and
#: ``len(AGENTS)`` once no agent waits (the trial has ended).
AGENTS: tuple[str, ...] = tuple(str(spec.key) for spec in agent_specs())
#: Brick statuses; ``brick_status`` holds indexes into it.
STATUSES: tuple[BrickStatus, ...] = tuple(BrickStatus)
#: The characters of JSON text as the environment writes it (ASCII; others escaped).
CHARSET = string.printable
#: The longest action: an answer as long as a model's may be, and its wrapper.
MAX_ACTION_CHARS = MAX_ANSWER_CHARS + 1_000
#: Bounds of the real-valued arrays (SI units): far beyond any measurement of the scene.
BOUND = 1e6


def action_space() -> spaces.Text:
    """One agent's answer or one tool call, as JSON text."""
    return spaces.Text(max_length=MAX_ACTION_CHARS, min_length=0, charset=CHARSET)


def observation_space(bricks: int) -> spaces.Dict:
    """The measured state of a scene with ``bricks`` bricks (one per target)."""

    def real(*shape: int) -> spaces.Box:
        return spaces.Box(-BOUND, BOUND, shape=shape, dtype=np.float64)

    return spaces.Dict(
        {
            "agent": spaces.Discrete(len(AGENTS) + 1),
            "time_s": real(1),
            "tool_pose": real(7),
            "joint_positions": real(7),
            "gripper_width": real(1),
            "finger_forces": real(2),
            "brick_poses": real(bricks, 7),
            "brick_velocities": real(bricks, 6),
            "brick_sizes": real(bricks, 3),
            "brick_status": spaces.MultiDiscrete([len(STATUSES)] * bricks),
            "placed": spaces.MultiBinary(bricks),
            "target_poses": real(bricks, 7),
            "state": spaces.Text(max_length=10_000 + 5_000 * bricks, min_length=2, charset=CHARSET),
        }
    )


def observation(state: WorldState, agent: str | None) -> dict[str, Any]:
    """The observation of ``state`` with ``agent`` waiting (None: none waits)."""
    robot, bricks, placed = state.robot, state.bricks, set(state.progress.placed_ids)

    def array(rows: Any) -> np.ndarray:
        return np.array(rows, dtype=np.float64)

    return {
        "agent": AGENTS.index(agent) if agent is not None else len(AGENTS),
        "time_s": array([state.time_s]),
        "tool_pose": array(_pose(robot.ee_pose)),
        "joint_positions": array(robot.joint_positions_rad),
        "gripper_width": array([robot.gripper_width_m]),
        "finger_forces": array(robot.finger_forces_n),
        "brick_poses": array([_pose(b.pose) for b in bricks]),
        "brick_velocities": array(
            [(*b.linear_velocity_mps, *b.angular_velocity_radps) for b in bricks]
        ),
        "brick_sizes": array([b.size_m for b in bricks]),
        "brick_status": np.array([STATUSES.index(b.status) for b in bricks], dtype=np.int64),
        "placed": np.array([b.id in placed for b in bricks], dtype=np.int8),
        "target_poses": array([_pose(t.pose) for t in state.goal.targets]),
        "state": json.dumps(state.model_dump(mode="json"), separators=(",", ":")),
    }


def _pose(pose: Pose) -> tuple[float, ...]:
    return (*pose.position_m, *pose.quat_xyzw)
