"""The knowledge base's formulas as prompt text, each with a worked example.

The text of a formula is ``prompts/formulas/NAME.md.j2``; its worked example is computed
here by the functions of ``tools/formulas.py`` (which the built-in reasoner and the
``solve`` tier's tools compute with), from fixed example poses, so that an example can never
disagree with what is computed.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from functools import cache
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined
from scipy.spatial.transform import Rotation

from actionreasoning.tools import formulas as f
from actionreasoning.world.geometry import as_quat, quat_yaw, round_floats, top_down_quat, yaw_quat
from actionreasoning.world.models import Pose

_ENVIRONMENT = Environment(
    loader=PackageLoader("actionreasoning.agents", "prompts/formulas"),
    undefined=StrictUndefined,
    keep_trailing_newline=True,
    autoescape=False,
)
#: Digits of the numbers in a worked example (as the state's: 0.01 mm, 1e-5).
DIGITS = 5


def _show(value: Any) -> str:
    """A number or a vector as JSON, rounded to DIGITS."""
    return json.dumps(round_floats(value, DIGITS), separators=(", ", ": "))


def _deg(angle_deg: float) -> str:
    return f"{round(angle_deg, 2):g}"


#: Example poses the worked examples start from (positions in m).
BRICK = Pose(position_m=(0.45, -0.3, 0.03), quat_xyzw=yaw_quat(math.radians(130.0)))
BRICK_SIZE_M = (0.2, 0.095, 0.06)
TARGET = Pose(position_m=(0.55, 0.1, 0.09), quat_xyzw=yaw_quat(math.radians(100.0)))
#: A brick held 2 mm off centre and 4 mm deep, level under the tool (a half turn about its
#: x axis: the tool points down, the brick up) and then rolled 8 deg about the pads' axis
#: (the tool's y axis).
TOOL = Pose(position_m=(0.5, 0.1, 0.35), quat_xyzw=top_down_quat(math.radians(20.0)))
OFFSET_IN_HAND_M = (0.002, -0.001, 0.004)
ROLL_IN_HAND = Rotation.from_euler("y", 8.0, degrees=True) * Rotation.from_euler(
    "x", 180.0, degrees=True
)


def _quaternions() -> dict[str, str]:
    q = yaw_quat(math.radians(30.0))
    v = (0.1, 0.0, 0.05)
    return {
        "q": _show(q),
        "v": _show(v),
        "rotated": _show(Rotation.from_quat(q).apply(v).tolist()),
    }


def _grasp_yaws() -> dict[str, str]:
    yaws = f.grasp_yaws_deg(BRICK.quat_xyzw)
    turns = [
        (
            f.wrist_deg(BRICK.position_m, a),
            f.wrist_deg(TARGET.position_m, f.place_yaw_deg(a, BRICK.quat_xyzw, TARGET.quat_xyzw)),
        )
        for a in yaws
    ]
    best = min(yaws, key=lambda a: f.wrist_turn_deg(BRICK, TARGET, a))
    grasp = f.grasp_pose(BRICK, BRICK_SIZE_M, top_down_quat(math.radians(best)))
    return {
        "brick_xy": _show(BRICK.position_m[:2]),
        "brick_yaw": _deg(math.degrees(quat_yaw(BRICK.quat_xyzw))),
        "target_xy": _show(TARGET.position_m[:2]),
        "target_yaw": _deg(math.degrees(quat_yaw(TARGET.quat_xyzw))),
        "a0": _deg(yaws[0]),
        "a1": _deg(yaws[1]),
        "w0": _deg(turns[0][0]),
        "p0": _deg(turns[0][1]),
        "w1": _deg(turns[1][0]),
        "p1": _deg(turns[1][1]),
        "a": _deg(best),
        "quat": _show(grasp.quat_xyzw),
        "approach": _show(f.approach_pose(grasp).position_m),
    }


def held_example() -> Pose:
    """The held brick of the worked examples, as measured."""
    return f.carried(TOOL, OFFSET_IN_HAND_M, as_quat(ROLL_IN_HAND.as_quat()))


def _in_hand() -> dict[str, str]:
    brick = held_example()
    offset, quat = f.in_hand(TOOL, brick)
    return {
        "tool_p": _show(TOOL.position_m),
        "tool_q": _show(TOOL.quat_xyzw),
        "brick_p": _show(brick.position_m),
        "brick_q": _show(brick.quat_xyzw),
        "offset": _show(offset),
        "quat": _show(quat),
    }


#: Two measurements of the example brick's roll, a quarter of a second apart, and the
#: duration of its set-down.
ROLL_WATCH = {"before_s": 100.0, "before_deg": 7.25, "now_s": 100.25, "now_deg": 8.0}
SET_DOWN_S = 1.0


def _roll_rate() -> dict[str, str]:
    offset, quat = f.in_hand(TOOL, held_example())
    w = ROLL_WATCH
    rate = f.roll_rate_deg_s(w["before_deg"], w["before_s"], w["now_deg"], w["now_s"])
    turn = f.touch_down_turn_deg(rate, SET_DOWN_S)
    rolled_offset, rolled_quat = f.rolled_in_hand(offset, quat, turn)
    return {
        "roll": _deg(f.roll_in_hand_deg(quat)),
        "creep_max": f"{f.CREEP_MAX_DEG_S:g}",
        "before": f"{w['before_deg']:g} deg at {w['before_s']:g} s",
        "now": f"{w['now_deg']:g} deg at {w['now_s']:g} s",
        "rate": _deg(rate),
        "duration": f"{SET_DOWN_S:g}",
        "turn": _deg(turn),
        "offset": _show(rolled_offset),
        "quat": _show(rolled_quat),
    }


def _slot_pose() -> dict[str, str]:
    slot = f.slot_pose(TARGET, *f.in_hand(TOOL, held_example()))
    return {
        "target_p": _show(TARGET.position_m),
        "target_q": _show(TARGET.quat_xyzw),
        "quat": _show(slot.quat_xyzw),
        "position": _show(slot.position_m),
    }


def _duration() -> dict[str, str]:
    start, end, speed = (0.5, 0.0, 0.1), (0.5, 0.3, 0.5), 0.2
    return {
        "start": _show(start),
        "end": _show(end),
        "speed": f"{speed:g}",
        "distance": f"{math.dist(start, end):g}",
        "duration": f"{f.move_duration_s(start, end, speed):g}",
    }


_EXAMPLES: dict[str, Callable[[], dict[str, str]]] = {
    "quaternions": _quaternions,
    "grasp_yaws": _grasp_yaws,
    "in_hand": _in_hand,
    "roll_rate": _roll_rate,
    "slot_pose": _slot_pose,
    "duration": _duration,
}
#: The formulas an agent may be given, by name.
FORMULAS: tuple[str, ...] = tuple(_EXAMPLES)


@cache
def formula_text(name: str) -> str:
    """The prompt text of formula ``name`` with its worked example."""
    return _ENVIRONMENT.get_template(f"{name}.md.j2").render(**_EXAMPLES[name]())
