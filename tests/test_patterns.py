"""Goal patterns: built-in geometry, example files and every way a pattern file is refused."""

from __future__ import annotations

import itertools
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml

from actionreasoning.errors import PatternError
from actionreasoning.world.geometry import quat_yaw, wrap_angle
from actionreasoning.world.models import GoalPattern
from actionreasoning.world.patterns import brick_size_limits, load_pattern
from actionreasoning.world.scenarios import PATTERNS
from actionreasoning.world.scene_spec import SceneSpec

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "patterns"
SPEC = SceneSpec()
L, W, H = SPEC.brick_size_m
SIZE = [L, W, H]


def _layers(goal: GoalPattern) -> list[list[np.ndarray]]:
    """Target centres grouped by layer (bottom first), each sorted along the build row."""
    row = _row_axis()
    by_z: dict[float, list[np.ndarray]] = {}
    for target in goal.targets:
        centre = np.asarray(target.pose.position_m)
        by_z.setdefault(round(centre[2], 9), []).append(centre)
    return [sorted(by_z[z], key=lambda c: float(c @ row)) for z in sorted(by_z)]


def _row_axis() -> np.ndarray:
    yaw = SPEC.build_yaw_rad
    return np.array([math.cos(yaw), math.sin(yaw), 0.0])


def _row_gaps(layer: list[np.ndarray]) -> list[float]:
    return [float((b - a) @ _row_axis()) - L for a, b in itertools.pairwise(layer)]


def _brick(x: float, y: float, z: float, yaw: float = 0.0) -> dict:
    return {"position": [x, y, z], "yaw_deg": yaw}


def _pattern(*bricks: dict, **fields: object) -> dict:
    return {"name": "test", "brick_size": SIZE, "bricks": list(bricks), **fields}


def _write(tmp_path: Path, name: str, data: object) -> Path:
    path = tmp_path / name
    text = json.dumps(data) if path.suffix == ".json" else yaml.safe_dump(data)
    path.write_text(text)
    return path


def _refused(path: Path, *needles: str) -> str:
    """Assert loading ``path`` fails with a one-line message naming the file and ``needles``."""
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    message = str(info.value)
    assert "\n" not in message
    assert path.name in message
    for needle in needles:
        assert needle in message, message
    return message


# --- built-ins -------------------------------------------------------------------------------


def test_builtin_names() -> None:
    assert set(PATTERNS) == {"pyramid", "grid", "wall"}


def test_pyramid_geometry() -> None:
    goal = load_pattern("pyramid", SPEC)
    assert goal.name == "pyramid" and goal.gap_m == 0.05 and len(goal.targets) == 6
    assert [t.index for t in goal.targets] == list(range(6))
    layers = _layers(goal)
    assert [len(layer) for layer in layers] == [3, 2, 1]
    for gap in _row_gaps(layers[0]) + _row_gaps(layers[1]):
        assert gap == pytest.approx(0.05, abs=1e-9)
    for upper, (left, right) in zip(
        layers[1], zip(layers[0], layers[0][1:], strict=False), strict=False
    ):
        np.testing.assert_allclose(upper[:2], ((left + right) / 2.0)[:2], atol=1e-9)
    top_mid = (layers[1][0] + layers[1][1]) / 2.0
    np.testing.assert_allclose(layers[2][0][:2], top_mid[:2], atol=1e-9)
    for k, layer in enumerate(layers):
        assert all(c[2] == pytest.approx((k + 0.5) * H, abs=1e-12) for c in layer)
    for target in goal.targets:
        turn = wrap_angle(quat_yaw(target.pose.quat_xyzw) - SPEC.build_yaw_rad)
        assert turn == pytest.approx(0.0, abs=1e-9)
    np.testing.assert_allclose(np.mean(layers[0], axis=0)[:2], SPEC.build_center_m[:2], atol=1e-9)


def test_pyramid_build_order_is_bottom_up_left_to_right() -> None:
    centres = [np.asarray(t.pose.position_m) for t in load_pattern("pyramid", SPEC).targets]
    keys = [(round(c[2], 9), float(c @ _row_axis())) for c in centres]
    assert keys == sorted(keys)


def test_grid_geometry() -> None:
    goal = load_pattern("grid", SPEC)
    assert goal.gap_m == 0.02 and len(goal.targets) == 6
    bottom, top = _layers(goal)
    assert len(bottom) == len(top) == 3
    for gap in _row_gaps(bottom) + _row_gaps(top):
        assert gap == pytest.approx(0.02, abs=1e-9)
    for lower, upper in zip(bottom, top, strict=False):
        np.testing.assert_allclose(upper[:2], lower[:2], atol=1e-12)
        assert upper[2] - lower[2] == pytest.approx(H)


# --- files -----------------------------------------------------------------------------------


@pytest.mark.parametrize("path", sorted(EXAMPLES.iterdir()), ids=lambda p: p.name)
def test_example_loads(path: Path) -> None:
    goal = load_pattern(path, SPEC)
    assert goal.gap_m is None and goal.targets
    assert all(SPEC.reach.contains(*t.pose.position_m) for t in goal.targets)


def test_example_files_present() -> None:
    names = {p.name for p in EXAMPLES.iterdir()}
    assert {"pyramid.json", "grid.yaml", "wall_rotated.yaml", "crosswise.json"} <= names


def test_pyramid_file_matches_builtin() -> None:
    from_file = load_pattern(EXAMPLES / "pyramid.json", SPEC).targets
    builtin = load_pattern("pyramid", SPEC).targets
    for a, b in zip(from_file, builtin, strict=True):
        np.testing.assert_allclose(a.pose.position_m, b.pose.position_m, atol=1e-12)


def test_explicit_origin_is_world_axes(tmp_path: Path) -> None:
    data = _pattern(_brick(0.1, 0.0, H / 2, 30.0), origin=[0.5, 0.0, 0.0])
    path = _write(tmp_path, "o.yaml", data)
    (target,) = load_pattern(path, SPEC).targets
    np.testing.assert_allclose(target.pose.position_m, (0.6, 0.0, H / 2), atol=1e-12)
    assert quat_yaw(target.pose.quat_xyzw) == pytest.approx(math.radians(30.0))


def test_touching_bricks_are_fine(tmp_path: Path) -> None:
    data = _pattern(_brick(-L / 2, 0, H / 2), _brick(L / 2, 0, H / 2))
    path = _write(tmp_path, "touch.json", data)
    assert len(load_pattern(path, SPEC).targets) == 2


# --- refusals --------------------------------------------------------------------------------


def test_missing_file(tmp_path: Path) -> None:
    _refused(tmp_path / "missing.json", "cannot read")


def test_directory(tmp_path: Path) -> None:
    path = tmp_path / "folder.yaml"
    path.mkdir()
    _refused(path, "cannot read")


def test_not_json(tmp_path: Path) -> None:
    path = tmp_path / "bad.json"
    path.write_text("name: this is YAML, not JSON\n")
    _refused(path, "not valid JSON")


def test_yaml_top_level_list(tmp_path: Path) -> None:
    _refused(_write(tmp_path, "list.yaml", [_brick(0, 0, H / 2)]), "top level", "list")


def test_unknown_extension(tmp_path: Path) -> None:
    _refused(_write(tmp_path, "pattern.txt", _pattern(_brick(0, 0, H / 2))), "'.txt'")


def test_missing_bricks(tmp_path: Path) -> None:
    path = _write(tmp_path, "nobricks.json", {"name": "x", "brick_size": SIZE})
    _refused(path, "bricks:", "required")


def test_string_for_number(tmp_path: Path) -> None:
    data = _pattern(_brick(0, 0, H / 2), _brick(0, "left", H / 2))
    _refused(_write(tmp_path, "str.yaml", data), "bricks[1].position[1]", "number")


def test_nan(tmp_path: Path) -> None:
    path = tmp_path / "nan.json"
    bricks = ", ".join(f'{{"position": [{x}, 0.0, 0.03]}}' for x in ("-0.22", "0.0", "NaN"))
    path.write_text(f'{{"name": "n", "brick_size": [0.2, 0.095, 0.06], "bricks": [{bricks}]}}')
    _refused(path, "bricks[2].position[0]", "finite number")


def test_negative_size(tmp_path: Path) -> None:
    data = _pattern(_brick(0, 0, H / 2)) | {"brick_size": [0.2, -0.095, 0.06]}
    _refused(_write(tmp_path, "neg.json", data), "brick_size[1]", "greater than 0")


def test_empty_brick_list(tmp_path: Path) -> None:
    _refused(_write(tmp_path, "empty.yaml", _pattern()), "bricks:", "at least 1")


def test_unreachable(tmp_path: Path) -> None:
    data = _pattern(_brick(0.5, 0, H / 2), _brick(0.1, 0.1, H / 2), origin=[0.0, 0.0, 0.0])
    path = _write(tmp_path, "far.json", data)
    _refused(path, "brick 1 ", "(0.100, 0.100, 0.030)", "0.42", "0.76", "0.45")


def test_overlap(tmp_path: Path) -> None:
    data = _pattern(_brick(-0.3, 0, H / 2), _brick(0, 0, H / 2), _brick(0.05, 0.05, H / 2, 90))
    _refused(_write(tmp_path, "overlap.yaml", data), "bricks 1 and 2 overlap")


def test_below_ground(tmp_path: Path) -> None:
    data = _pattern(_brick(0, 0, H / 2), _brick(0, 0.1, H / 2 - 0.005))
    _refused(_write(tmp_path, "sunk.json", data), "brick 1 ", "below the ground")


def test_floating(tmp_path: Path) -> None:
    data = _pattern(_brick(0, 0, H / 2), _brick(0, 0, 1.5 * H + 0.01))
    _refused(_write(tmp_path, "float.yaml", data), "brick 1 ", "nothing under it")


def test_rests_on_later_brick(tmp_path: Path) -> None:
    data = _pattern(_brick(0.3, 0, H / 2), _brick(0, 0, 1.5 * H), _brick(0, 0, H / 2))
    _refused(_write(tmp_path, "order.json", data), "brick 1 rests on brick 2, which is built later")


def test_overhang_topples(tmp_path: Path) -> None:
    data = _pattern(_brick(0, 0, H / 2), _brick(0.15, 0, 1.5 * H))
    _refused(_write(tmp_path, "overhang.yaml", data), "brick 1 ", "topple")


def test_a_pattern_far_beyond_the_scene_is_refused_in_a_short_line(tmp_path: Path) -> None:
    path = _write(tmp_path, "far.json", _pattern(_brick(0, 0, H / 2), origin=[1e300, 0, 0]))
    with pytest.raises(PatternError) as info:
        load_pattern(path, SPEC)
    assert str(info.value) == (
        f"{path}: brick 0 at world (1e+300, 0.000, 0.030) is out of the arm's reach "
        "(radius 0.42-0.76 m, height 0-0.45 m)"
    )


def test_the_docs_state_the_brick_size_limits_the_code_applies() -> None:
    """docs/patterns.md said widths of 0.07-0.12 m while the code took up to 0.143 m."""
    text = " ".join((Path(__file__).parents[1] / "docs" / "patterns.md").read_text().split())
    names = ("length", "width across the gripper", "height")
    for name, (low, high) in zip(names, brick_size_limits(SceneSpec()), strict=True):
        stated = re.search(rf"{name} (\S+)–(\S+) m", text)
        assert stated is not None, name
        assert stated.groups() == (f"{low:.3f}", f"{high:.3f}"), name
