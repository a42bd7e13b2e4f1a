"""The environment's spaces: the measured world state as arrays plus its JSON text (and,
when the agents observe pictures, the cameras' pictures as arrays), and an action as JSON
text."""

from __future__ import annotations

import json
import re
import string
from collections.abc import Sequence
from functools import cached_property
from typing import Any

import numpy as np
from gymnasium import spaces

from actionreasoning.agents.observation import DEFAULT_OBSERVATION, Observation
from actionreasoning.agents.spec import agent_specs
from actionreasoning.agents.validation import MAX_ANSWER_CHARS
from actionreasoning.world.models import BrickStatus, Pose, WorldState
from actionreasoning.world.pictures import (
    DEPTH_UNIT_M,
    SHOWN,
    Picture,
    PictureKind,
    picture_name,
    read_colour,
    read_depth,
)

#: The agents in pipeline order; the observation's ``agent`` is an index into it, and
#: ``len(AGENTS)`` once no agent waits (the trial has ended).
AGENTS: tuple[str, ...] = tuple(str(spec.key) for spec in agent_specs())
#: Brick statuses; ``brick_status`` holds indexes into it.
STATUSES: tuple[BrickStatus, ...] = tuple(BrickStatus)
#: The characters of JSON text as the environment writes it (ASCII; others escaped).
CHARSET = string.printable
#: The longest action: an answer as long as a model's may be, and its wrapper.
MAX_ACTION_CHARS = MAX_ANSWER_CHARS + 1_000
#: The characters an action may hold, as inclusive ranges of code points: every character
#: JSON text can hold (any Unicode scalar value, as UTF-8 carries it: no surrogates) but the
#: control characters below U+0020 other than tab, newline and carriage return.
ACTION_CODE_POINTS: tuple[tuple[int, int], ...] = (
    (0x09, 0x0A),
    (0x0D, 0x0D),
    (0x20, 0xD7FF),
    (0xE000, 0x10FFFF),
)
_FOREIGN = re.compile(
    "[^" + "".join(f"\\U{lo:08x}-\\U{hi:08x}" for lo, hi in ACTION_CODE_POINTS) + "]"
)
_LOWS = np.array([lo for lo, _ in ACTION_CODE_POINTS])
_SIZES = np.array([hi - lo + 1 for lo, hi in ACTION_CODE_POINTS])
#: Where each range starts in the action space's character list, and how long that is.
_STARTS, _COUNT = np.cumsum(_SIZES) - _SIZES, int(_SIZES.sum())
#: Bounds of the real-valued arrays (SI units): far beyond any measurement of the scene.
BOUND = 1e6


class ActionText(spaces.Text):
    """Gymnasium's ``Text`` of 0 to ``max_length`` characters of :data:`ACTION_CODE_POINTS`.

    Its charset is 1.1 million characters: listing them, as ``Text`` does when made, takes
    seconds and 200 MB, so they are listed only when asked for (``character_list``, masked
    sampling); membership, sampling and ``character_index`` work on the code points.
    """

    def __init__(self, max_length: int) -> None:
        spaces.Space.__init__(self, dtype=str)  # not Text's: it lists the charset
        self.min_length, self.max_length = 0, max_length

    def contains(self, x: Any) -> bool:
        """Whether ``x`` is text of at most ``max_length`` characters the space admits."""
        return isinstance(x, str) and len(x) <= self.max_length and foreign_character(x) is None

    def sample(
        self,
        mask: tuple[int | None, np.ndarray | None] | None = None,
        probability: tuple[int | None, np.ndarray | None] | None = None,
    ) -> str:
        """Uniform characters of a uniform length; with a mask or probabilities, as ``Text``."""
        if mask is not None or probability is not None:
            return super().sample(mask, probability)
        length = self.np_random.integers(self.min_length, self.max_length + 1)
        indexes = self.np_random.integers(0, _COUNT, size=length)
        ranges = np.searchsorted(_STARTS, indexes, side="right") - 1
        codes = _LOWS[ranges] + indexes - _STARTS[ranges]
        return "".join(map(chr, codes.tolist()))

    def character_index(self, char: str) -> np.int32:
        """The index of ``char`` in :attr:`character_list` (KeyError if it has none)."""
        code = ord(char)
        for (lo, hi), start in zip(ACTION_CODE_POINTS, _STARTS, strict=True):
            if lo <= code <= hi:
                return np.int32(start + code - lo)
        raise KeyError(char)

    @cached_property
    def characters(self) -> str:
        """Every character of the space, in code point order."""
        return "".join(chr(code) for lo, hi in ACTION_CODE_POINTS for code in range(lo, hi + 1))

    @cached_property
    def character_list(self) -> tuple[str, ...]:
        """Every character of the space, in code point order."""
        return tuple(self.characters)

    @cached_property
    def character_set(self) -> frozenset[str]:
        """Every character of the space."""
        return frozenset(self.characters)

    def __eq__(self, other: object, /) -> bool:
        return isinstance(other, ActionText) and self.max_length == other.max_length

    def __repr__(self) -> str:
        return f"ActionText(0, {self.max_length}, charset=ACTION_CODE_POINTS)"


def foreign_character(text: str) -> int | None:
    """The index of the first character of ``text`` no action may hold, or None."""
    found = _FOREIGN.search(text)
    return None if found is None else found.start()


def action_space() -> ActionText:
    """One agent's answer or one tool call, as JSON text."""
    return ActionText(max_length=MAX_ACTION_CHARS)


#: The deepest a depth picture holds (m): its 16-bit counts' range.
MAX_DEPTH_M = float(np.iinfo(np.uint16).max * DEPTH_UNIT_M)


def pictures_space() -> spaces.Dict:
    """The cameras' pictures, by name (``top_down.depth``): colour as height x width x 3
    uint8, depth as height x width float32 metres along the optical axis, 0 no reading."""
    boxes: dict[str, spaces.Space[Any]] = {}
    for camera, kinds in SHOWN:
        for kind in kinds:
            name = picture_name(camera.name, kind)
            size = (camera.height, camera.width)
            if kind is PictureKind.COLOUR:
                boxes[name] = spaces.Box(0, 255, shape=(*size, 3), dtype=np.uint8)
            else:
                boxes[name] = spaces.Box(0.0, MAX_DEPTH_M, shape=size, dtype=np.float32)
    return spaces.Dict(boxes)


def pictures(carried: Sequence[Picture]) -> dict[str, np.ndarray]:
    """The pictures a call carried as :func:`pictures_space` holds them."""
    return {
        picture.name: (
            read_colour(picture.png)
            if picture.kind is PictureKind.COLOUR
            else np.nan_to_num(read_depth(picture.png), nan=0.0)
        )
        for picture in carried
    }


#: The observation's arrays of the bricks' poses and states, which an agent that observes
#: the scene in pictures alone is not given.
BRICK_KEYS = ("brick_poses", "brick_velocities", "brick_sizes", "brick_status", "placed")


def observation_space(bricks: int, observe: Observation = DEFAULT_OBSERVATION) -> spaces.Dict:
    """The measured state of a scene with ``bricks`` bricks (one per target), and the
    cameras' pictures if ``observe`` sends them; without the bricks' arrays (BRICK_KEYS)
    if it shows no brick's pose."""

    def real(*shape: int) -> spaces.Box:
        return spaces.Box(-BOUND, BOUND, shape=shape, dtype=np.float64)

    extra: dict[str, spaces.Space[Any]] = {"pictures": pictures_space()} if observe.pictures else {}
    shown = {
        key: space
        for key, space in {
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
            **extra,
        }.items()
        if observe.poses or key not in BRICK_KEYS
    }
    return spaces.Dict(shown)


def observation(
    state: WorldState, agent: str | None, observe: Observation = DEFAULT_OBSERVATION
) -> dict[str, Any]:
    """The observation of ``state`` with ``agent`` waiting (None: none waits), as much of it
    as ``observe`` shows: no brick's pose in the image tier (its ``state`` text leaves out
    the bricks), and no pictures (``pictures`` adds them)."""
    robot, bricks, placed = state.robot, state.bricks, set(state.progress.placed_ids)

    def array(rows: Any) -> np.ndarray:
        return np.array(rows, dtype=np.float64)

    shown = {
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
        "state": json.dumps(
            state.model_dump(mode="json", exclude=None if observe.poses else {"bricks"}),
            separators=(",", ":"),
        ),
    }
    return {key: value for key, value in shown.items() if observe.poses or key not in BRICK_KEYS}


def _pose(pose: Pose) -> tuple[float, ...]:
    return (*pose.position_m, *pose.quat_xyzw)
