"""Goal patterns: ordered target brick poses, from built-ins or JSON/YAML files.

File format (``.json``, ``.yaml`` or ``.yml``; metres; see :class:`PatternFile`)::

    {name, brick_size: [x, y, z] or a catalogue name, origin: [x, y, z] (optional),
     supply: scattered|pallet|feeder (optional, default scattered),
     bricks: [{position, yaw_deg, size (optional: [x, y, z] or a catalogue name)}]}

A brick without ``size`` has the pattern's ``brick_size``; the catalogue names are those of
:data:`~actionreasoning.world.scene_spec.BRICK_CATALOGUE` (``full``, ``half``).

Frame rule (the public contract): each ``position`` is a brick centre relative to the
pattern origin, with z measured from the ground (a first-layer brick of height h has
z = h/2). With ``origin``, positions and yaw are in world axes and a brick's world centre
is ``origin + position`` (keep the origin's z at 0). Without ``origin``, the pattern is placed
in the scene's build-area frame: its origin at ``spec.build_center_m``, its x axis along the
build rows (world x turned by ``spec.build_yaw_rad`` about z), and ``yaw_deg`` measured
from that x axis. So x runs along a row and y points across the rows.

Every pattern is validated before anything runs (fields, a brick size the gripper holds,
ground, reach, overlaps, support, no more bricks than the pick area holds for every seed);
each problem is a one-line :class:`PatternError` naming the file or built-in and the field
or brick.
"""

from __future__ import annotations

import itertools
import json
import math
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from actionreasoning.errors import PatternError
from actionreasoning.world.boxes import Box
from actionreasoning.world.config_files import check_file_name, parse_model, read_mapping
from actionreasoning.world.geometry import Vec3, yaw_quat
from actionreasoning.world.models import GoalPattern, Pose, Supply, TargetBrick
from actionreasoning.world.pattern_file import PatternFile, brick_sizes
from actionreasoning.world.scenarios import PATTERNS, WallPattern
from actionreasoning.world.scene_spec import (
    BRICK_CATALOGUE,
    FINGERTIPS_BEYOND_TCP_M,
    GRIPPER_GAP_M,
    PALM_BEHIND_TCP_M,
    SceneSpec,
)
from actionreasoning.world.supply import capacity_error
from actionreasoning.world.support import (
    MIN_AREA_M2,
    SUPPORT_TOL_M,
    carriers,
    centre_is_held,
)
from actionreasoning.world.tolerances import Tolerances
from actionreasoning.world.walls import wall_length_m, wall_pattern

OVERLAP_TOL_M = 1e-3  # z-overlap allowed between bricks, and how far below ground a bottom goes
#: A brick's width is this much more than the gripper's closed gap, and this much less than
#: its open gap minus sigma_2's opening delta.
GRIP_MARGIN_M = 0.01
#: Grasped at its centre, a brick's bottom lies this much beyond the fingertips (they stay
#: off the ground) and its top this much short of the palm.
FINGERTIP_CLEARANCE_M = 0.0025
PALM_CLEARANCE_M = 0.0075
#: Every edge of a pattern's brick lies within these shares of the catalogue brick's edge.
SIZE_SHARES = (0.5, 1.5)


def _json_text(data: dict[str, Any]) -> str:
    """A pattern file's JSON as the example files have it: a field a line, a brick a line."""
    fields = [f"  {json.dumps(key)}: {json.dumps(value)}" for key, value in data.items()]
    bricks = ",\n".join(f"    {json.dumps(brick)}" for brick in data["bricks"])
    fields[list(data).index("bricks")] = f'  "bricks": [\n{bricks}\n  ]'
    return "{\n" + ",\n".join(fields) + "\n}\n"


def _yaml_text(data: dict[str, Any]) -> str:
    return yaml.safe_dump(data, sort_keys=False, default_flow_style=None)


#: How a pattern file of each suffix is written.
_DUMPERS: dict[str, Callable[[dict[str, Any]], str]] = {
    ".json": _json_text,
    ".yaml": _yaml_text,
    ".yml": _yaml_text,
}


def builtin_pattern(name: str, spec: SceneSpec) -> PatternFile:
    """The built-in ``name`` as a pattern file in the build-area frame (no origin)."""
    if name not in PATTERNS:
        raise PatternError(f"unknown built-in pattern '{name}' (known: {', '.join(PATTERNS)})")
    entry = PATTERNS[name]
    if isinstance(entry, WallPattern):
        length_m = wall_length_m(entry.full_bricks)
        return wall_pattern(length_m, entry.courses, entry.bond, supply=entry.supply, name=name)
    length, _, height = spec.brick_size_m
    pitch = length + entry.gap_m
    bricks = [
        {"position": [(i - (count - 1) / 2.0) * pitch, 0.0, (k + 0.5) * height], "yaw_deg": 0.0}
        for k, count in enumerate(entry.layers)
        for i in range(count)
    ]
    data = {"name": name, "brick_size": list(spec.brick_size_m), "bricks": bricks}
    return _parse(data, f"built-in pattern '{name}'")


def load_pattern(name_or_path: str | Path, spec: SceneSpec) -> GoalPattern:
    """A built-in (by name, of :data:`~actionreasoning.world.scenarios.PATTERNS`) or a
    pattern file, placed in the world and validated."""
    if isinstance(name_or_path, str) and name_or_path in PATTERNS:
        source, gap = f"built-in pattern '{name_or_path}'", PATTERNS[name_or_path].gap_m
        pattern = builtin_pattern(name_or_path, spec)
    else:
        check_file_name(name_or_path, "pattern", PatternError)
        source, gap = str(name_or_path), None
        pattern = _parse(read_mapping(Path(name_or_path), "pattern file", PatternError), source)
    return place_pattern(pattern, source, spec, gap)


def place_pattern(
    pattern: PatternFile, source: str, spec: SceneSpec, gap_m: float | None = None
) -> GoalPattern:
    """``pattern`` placed in the world and validated, each refusal naming ``source``; a
    pattern out of reach is refused for its reach whatever its supply holds."""
    sizes = brick_sizes(pattern)
    _check_brick_size(source, "brick_size", pattern.brick_size, spec)
    for i, brick in enumerate(pattern.bricks):
        if brick.size is not None:
            _check_brick_size(source, f"bricks[{i}].size", sizes[i], spec)
    blocks = _place(pattern, sizes, spec)
    _validate(source, blocks, spec)
    _check_pick_area(source, pattern.supply, sizes, spec)
    targets = tuple(
        TargetBrick(
            index=b.id, pose=Pose(position_m=b.position_m, quat_xyzw=b.quat_xyzw), size_m=b.size_m
        )
        for b in blocks
    )
    return GoalPattern(
        name=pattern.name,
        gap_m=gap_m,
        brick_size_m=pattern.brick_size,
        targets=targets,
        supply=pattern.supply,
    )


def save_pattern(pattern: PatternFile, path: Path, spec: SceneSpec) -> GoalPattern:
    """Write ``pattern`` to ``path`` (JSON or YAML by its suffix) if it is valid, and return
    it loaded back from there; a refusal names ``path`` and leaves no file behind.

    The file is written under a short temporary name beside ``path`` (a legal 255-byte
    name has no room for a longer one), loaded as any pattern file is, and only then
    renamed to ``path``; a write that fails (a full disk) leaves no temporary file.
    """
    suffix = path.suffix.lower()
    if suffix not in _DUMPERS:
        raise PatternError(f"{path}: unknown extension '{suffix}' (use .json, .yaml or .yml)")
    place_pattern(pattern, str(path), spec)
    text = _DUMPERS[suffix](pattern.model_dump(mode="json", exclude_none=True))
    temporary = path.with_name(f".pattern-{os.getpid()}{suffix}")
    try:
        try:
            with temporary.open("w", encoding="utf-8") as file:
                file.write(text)
            goal = load_pattern(temporary, spec)
            os.replace(temporary, path)
        finally:
            temporary.unlink(missing_ok=True)
    except OSError as exc:
        raise PatternError(f"{path}: cannot write pattern file ({exc.strerror or exc})") from exc
    return goal


def _parse(data: dict[str, Any], source: str) -> PatternFile:
    return parse_model(PatternFile, data, source, PatternError)


def _place(pattern: PatternFile, sizes: list[Vec3], spec: SceneSpec) -> list[Box]:
    """The pattern's bricks in the world frame (see the frame rule above)."""
    ox, oy, oz = pattern.origin or spec.build_center_m
    turn = spec.build_yaw_rad if pattern.origin is None else 0.0
    c, s = math.cos(turn), math.sin(turn)
    return [
        Box(
            (ox + c * x - s * y, oy + s * x + c * y, oz + z),
            yaw_quat(turn + math.radians(brick.yaw_deg)),
            size,
            id=i,
        )
        for i, (brick, size) in enumerate(zip(pattern.bricks, sizes, strict=True))
        for x, y, z in [brick.position]
    ]


def brick_size_limits(spec: SceneSpec) -> tuple[tuple[float, float], ...]:
    """The smallest and largest length, width and height of a pattern's brick.

    Each edge is within SIZE_SHARES of the catalogue's full brick's, and a length may be as
    short as the catalogue's shortest brick (a half brick). The gripper squeezes the width
    (y), so the pads must close on it and open wide enough to pass it (sigma_2). Grasped at
    its centre, the brick must reach past the fingertips and stay short of the palm.
    """
    low, high = SIZE_SHARES
    x, y, z = ((edge * low, edge * high) for edge in spec.brick_size_m)
    x = (min(x[0], *(size[0] for size in BRICK_CATALOGUE.values())), x[1])
    width = (
        GRIPPER_GAP_M[0] + GRIP_MARGIN_M,
        GRIPPER_GAP_M[1] - Tolerances().delta_m - GRIP_MARGIN_M,
    )
    height = (
        2.0 * (FINGERTIPS_BEYOND_TCP_M + FINGERTIP_CLEARANCE_M),
        2.0 * (PALM_BEHIND_TCP_M - PALM_CLEARANCE_M),
    )
    return (
        x,
        (max(y[0], width[0]), min(y[1], width[1])),
        (max(z[0], height[0]), min(z[1], height[1])),
    )


def _check_brick_size(source: str, field: str, size: Vec3, spec: SceneSpec) -> None:
    """Refuse a brick the gripper cannot hold, or of a size far from the catalogue brick's."""
    names = ("length", "width (across the gripper)", "height")
    for axis, (edge, (low, high), name) in enumerate(
        zip(size, brick_size_limits(spec), names, strict=True)
    ):
        if not low <= edge <= high:
            raise PatternError(
                f"{source}: {field}[{axis}]: {name} {edge:g} m is outside {low:.3f}-{high:.3f} "
                f"m (the gripper opens {GRIPPER_GAP_M[0]:g}-{GRIPPER_GAP_M[1]:g} m; "
                f"catalogue brick {_fmt(spec.brick_size_m)} m)"
            )


def _check_pick_area(source: str, supply: Supply, sizes: list[Vec3], spec: SceneSpec) -> None:
    """Refuse more bricks than the supply holds for every seed (see world/supply.py)."""
    error = capacity_error(supply, sizes, spec)
    if error is not None:
        raise PatternError(f"{source}: bricks: {error}")


def _validate(source: str, blocks: list[Box], spec: SceneSpec) -> None:
    """Refuse physically impossible or unreachable patterns."""
    for block in blocks:
        _check_ground(source, block)
        _check_reach(source, block, spec)
    _check_overlaps(source, blocks)
    for block in blocks:
        _check_support(source, block, blocks)


def _fmt(values: tuple[float, ...]) -> str:
    """Metres to the millimetre; a value far beyond the scene (1e300) in powers of ten."""
    return "(" + ", ".join(f"{v:.3f}" if abs(v) < 1e6 else f"{v:.3g}" for v in values) + ")"


def _check_ground(source: str, block: Box) -> None:
    if block.bottom_m < -OVERLAP_TOL_M:
        where = f"bottom face at z = {block.bottom_m:.3f} m"
        raise PatternError(f"{source}: brick {block.id} is below the ground ({where})")


def _check_reach(source: str, block: Box, spec: SceneSpec) -> None:
    band = spec.reach
    if not band.contains(*block.position_m):
        limits = f"radius {band.min_radius_m}-{band.max_radius_m} m, height 0-{band.max_height_m} m"
        raise PatternError(
            f"{source}: brick {block.id} at world {_fmt(block.position_m)} "
            f"is out of the arm's reach ({limits})"
        )


def _check_overlaps(source: str, blocks: list[Box]) -> None:
    for a, b in itertools.combinations(blocks, 2):
        z_overlap = min(a.top_m, b.top_m) - max(a.bottom_m, b.bottom_m)
        if z_overlap > OVERLAP_TOL_M and a.footprint.intersection(b.footprint).area > MIN_AREA_M2:
            raise PatternError(f"{source}: bricks {a.id} and {b.id} overlap")


def _check_support(source: str, block: Box, blocks: list[Box]) -> None:
    """A raised brick must rest, centre inside its support, on bricks built before it."""
    if block.bottom_m <= OVERLAP_TOL_M:
        return
    brick = f"{source}: brick {block.id}"
    contacts = carriers(block, blocks)
    if not contacts:
        raise PatternError(
            f"{brick} has nothing under it (no brick top within "
            f"{SUPPORT_TOL_M * 1e3:.0f} mm of z = {block.bottom_m:.3f} m)"
        )
    later = [other.id for other, _ in contacts if other.named_id > block.named_id]
    if later:
        raise PatternError(f"{brick} rests on brick {later[0]}, which is built later")
    if not centre_is_held(block, [area for _, area in contacts]):
        below = ", ".join(str(other.id) for other, _ in contacts)
        raise PatternError(
            f"{brick} would topple: its centre {_fmt(block.position_m[:2])} lies "
            f"outside its support on brick(s) {below}"
        )
