"""The built-in scenarios by name: goal patterns, physics profiles and noise levels.

Each kind is a :class:`Registry` of entries; the command's options (the names they take and
their help), the Gym env and the tests enumerate these, and :data:`SCENARIOS` is every
combination. Adding a built-in is one entry. Files of each kind are loaded beside the
built-ins: :func:`load_physics`, :func:`load_noise` and
:func:`~actionreasoning.world.patterns.load_pattern`.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Generic, TypeVar

from actionreasoning.world.config_files import load_named
from actionreasoning.world.models import Supply
from actionreasoning.world.noise import NoiseLevel, PerceptionNoise, PhysicalVariation
from actionreasoning.world.physics import PAPER, PRECISE, PhysicsProfile
from actionreasoning.world.walls import JOINT_M, Bond

T = TypeVar("T")


@dataclass(frozen=True)
class Builtin(Generic[T]):
    """A built-in scenario part: its name, what it is, and a few words for ``--help``."""

    name: str
    value: T
    help: str = ""


class Registry(Mapping[str, T]):
    """The built-ins of one kind (``what``: "physics profile"), by name, in order."""

    def __init__(self, what: str, *entries: Builtin[T]) -> None:
        self.what = what
        self.entries = entries
        self._values = {entry.name: entry.value for entry in entries}
        if len(self._values) != len(entries):
            raise ValueError(f"two built-in {what}s share a name")
        for entry in entries:  # a named value (a profile, a level) goes by its own name
            if getattr(entry.value, "name", entry.name) != entry.name:
                raise ValueError(f"built-in {what} '{entry.name}' is named otherwise")

    def __getitem__(self, name: str) -> T:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)


@dataclass(frozen=True)
class RowPattern:
    """A built-in pattern: bricks per layer, each layer a row centred over the one below,
    ``gap_m`` apart in a row."""

    layers: tuple[int, ...]
    gap_m: float


@dataclass(frozen=True)
class WallPattern:
    """A built-in straight wall (world/walls.py): ``courses`` courses of ``full_bricks`` full
    bricks (a running bond's shifted courses: half bricks at the ends), from ``supply``."""

    courses: int
    full_bricks: int
    bond: Bond
    supply: Supply

    @property
    def gap_m(self) -> float:
        """The joint between neighbouring bricks of a course, as a row pattern's gap."""
        return JOINT_M


PATTERNS: Registry[RowPattern | WallPattern] = Registry(
    "pattern",
    Builtin("pyramid", RowPattern(layers=(3, 2, 1), gap_m=0.05)),
    Builtin("grid", RowPattern(layers=(3, 3), gap_m=0.02)),
    Builtin("wall", WallPattern(courses=3, full_bricks=4, bond=Bond.RUNNING, supply=Supply.PALLET)),
)

PHYSICS: Registry[PhysicsProfile] = Registry(
    "physics profile",
    Builtin("paper", PAPER, "PyBullet's defaults, the paper's condition"),
    Builtin("precise", PRECISE, "tuned until nothing slips"),
)

NOISE: Registry[NoiseLevel] = Registry(
    "noise level",
    Builtin("none", NoiseLevel(name="none")),
    Builtin(
        "low",
        NoiseLevel(
            name="low",
            perception=PerceptionNoise(position_std_m=0.001, yaw_std_deg=0.5, force_rel_std=0.05),
            variation=PhysicalVariation(friction_rel=0.10, mass_rel=0.10, size_m=0.001),
        ),
    ),
    Builtin(
        "medium",
        NoiseLevel(
            name="medium",
            perception=PerceptionNoise(position_std_m=0.002, yaw_std_deg=1.0, force_rel_std=0.10),
            variation=PhysicalVariation(friction_rel=0.20, mass_rel=0.20, size_m=0.002),
        ),
    ),
    Builtin(
        "high",
        NoiseLevel(
            name="high",
            perception=PerceptionNoise(position_std_m=0.004, yaw_std_deg=2.0, force_rel_std=0.20),
            variation=PhysicalVariation(friction_rel=0.35, mass_rel=0.35, size_m=0.003),
        ),
    ),
)


@dataclass(frozen=True)
class Scenario:
    """One combination of built-ins by name: ``eval``'s, ``Conditions.load``'s and the Gym
    env's ``pattern``, ``physics`` and ``noise``."""

    pattern: str
    physics: str
    noise: str

    def __str__(self) -> str:
        return f"{self.pattern}-{self.physics}-{self.noise}"


#: Every built-in pattern under every physics profile and noise level.
SCENARIOS = tuple(Scenario(*names) for names in itertools.product(PATTERNS, PHYSICS, NOISE))


def load_physics(name_or_path: str | Path) -> PhysicsProfile:
    """A built-in profile by name, or a profile file (JSON/YAML), validated."""
    return load_named(name_or_path, PHYSICS, PhysicsProfile, PHYSICS.what)


def load_noise(name_or_path: str | Path) -> NoiseLevel:
    """A named level, or a noise file (JSON/YAML), validated."""
    return load_named(name_or_path, NOISE, NoiseLevel, NOISE.what)
