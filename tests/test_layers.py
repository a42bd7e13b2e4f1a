"""The layering: agents, tools and reasoners work without PyBullet, the simulator provides
what the tools ask of it, and the command loads the simulator and the model clients only
for the commands that run them."""

from __future__ import annotations

import ast
import inspect
import os
import subprocess
import sys
from dataclasses import fields
from pathlib import Path

import pytest
from test_run_dir import manifest, result

from actionreasoning.sim.collision import CollisionChecker
from actionreasoning.sim.kinematics import IKSolution, KinematicArm
from actionreasoning.tools.ports import ArmModel, ClearanceChecker, IKResult
from actionreasoning.world.physics import PRECISE

REASONING = (
    "actionreasoning.agents.orchestrator",
    "actionreasoning.tools.registry",
    "actionreasoning.reasoners.builtin",
    "actionreasoning.reasoners.factory",
    "actionreasoning.reasoners.reference_model",
    "actionreasoning.runs.summary",
)
NO_PYBULLET = "import sys; sys.modules['pybullet'] = None\n"
#: PyBullet and the package that wraps it, whose __init__ imports PyBullet with stderr shut
#: (so out of an importtime log).
SIMULATOR = ("pybullet", "actionreasoning.sim")


def python(*args: str) -> subprocess.CompletedProcess[str]:
    """Python run with ``args``, its output not wrapped."""
    env = {**os.environ, "COLUMNS": "1000"}
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, timeout=300, check=False, env=env
    )


def write_run(out: Path) -> None:
    """A finished run of three trials, written by hand (no simulation)."""
    out.mkdir()
    (out / "run.json").write_text(manifest(physics=PRECISE).model_dump_json())
    lines = [result(trial, success=trial != 1).model_dump_json() + "\n" for trial in range(3)]
    (out / "results.jsonl").write_text("".join(lines))


def loaded(stderr: str, *packages: str) -> list[str]:
    """The modules of ``packages`` in the log of a ``-X importtime`` run."""
    lines = [line for line in stderr.splitlines() if line.startswith("import time:")]
    names = [line.rsplit("|", 1)[-1].strip() for line in lines]
    return [n for n in names if any(n == p or n.startswith(f"{p}.") for p in packages)]


def test_the_reasoning_layer_imports_with_pybullet_unimportable() -> None:
    loaded = python("-c", NO_PYBULLET + "".join(f"import {name}\n" for name in REASONING))
    assert loaded.returncode == 0, loaded.stderr
    blocked = python("-c", NO_PYBULLET + "import actionreasoning.sim.scene")
    assert "ModuleNotFoundError" in blocked.stderr  # the block holds where PyBullet is needed


def test_importing_the_orchestrator_loads_no_pybullet() -> None:
    run = python("-X", "importtime", "-c", "import actionreasoning.agents.orchestrator")
    assert run.returncode == 0, run.stderr
    assert loaded(run.stderr, "actionreasoning.agents.orchestrator")
    assert not loaded(run.stderr, *SIMULATOR)


@pytest.mark.parametrize(
    ("command", "shown", "unused"),
    [
        (["--help"], "Usage", ("openai", "matplotlib")),
        (["pattern", "pyramid"], "6 bricks, valid", ("openai", "matplotlib")),
        (["report", "RUN", "--out", "REPORT"], "report.html", ("openai",)),
    ],
)
def test_commands_that_read_files_load_neither_simulator_nor_model_client(
    command: list[str], shown: str, unused: tuple[str, ...], tmp_path: Path
) -> None:
    write_run(tmp_path / "run")
    paths = {"RUN": str(tmp_path / "run"), "REPORT": str(tmp_path / "report")}
    run = python("-X", "importtime", "-m", "actionreasoning", *(paths.get(a, a) for a in command))
    assert run.returncode == 0, run.stderr
    assert shown in run.stdout
    assert not loaded(run.stderr, *SIMULATOR, *unused)


def test_a_classical_eval_loads_no_model_client(tmp_path: Path, small_pattern: Path) -> None:
    """The backends' clients load when a backend asking a model is built, not before. The
    trial runs until its step budget (700 steps: past the spawn settle, into the script)."""
    out = tmp_path / "eval"
    run = python(
        *("-X", "importtime", "-m", "actionreasoning", "eval", "--method", "classical"),
        *("--pattern", str(small_pattern), "--trials", "1", "--max-steps", "700"),
        *("--out", str(out)),
    )
    assert run.returncode == 0, run.stderr
    assert len((out / "results.jsonl").read_text().splitlines()) == 1
    assert loaded(run.stderr, "actionreasoning.reasoners.factory", "actionreasoning.sim")
    assert not loaded(run.stderr, "openai", "llama_cpp", "actionreasoning.reasoners.openai_chat")


def _parameters(function: object) -> list[inspect.Parameter]:
    return [p for p in inspect.signature(function).parameters.values() if p.name != "self"]


@pytest.mark.parametrize(
    ("protocol", "concrete"), [(ArmModel, KinematicArm), (ClearanceChecker, CollisionChecker)]
)
def test_the_simulator_provides_what_the_tools_ask_for(protocol: type, concrete: type) -> None:
    """Each protocol method exists with the same parameters, in order, with the same
    defaults; the simulator's extra parameters have defaults."""
    for name, wanted in vars(protocol).items():
        if name.startswith("_") or not callable(wanted):
            continue
        given = _parameters(getattr(concrete, name))
        asked = _parameters(wanted)
        assert [(p.name, p.kind, p.default) for p in given[: len(asked)]] == [
            (p.name, p.kind, p.default) for p in asked
        ], name
        assert all(p.default is not p.empty for p in given[len(asked) :]), name


def test_an_ik_solution_is_an_ik_result(arm: KinematicArm) -> None:
    wanted = {name for name, member in vars(IKResult).items() if isinstance(member, property)}
    given = {f.name for f in fields(IKSolution)} | {
        name for name, member in vars(IKSolution).items() if isinstance(member, property)
    }
    assert wanted == given
    assert isinstance(arm, ArmModel) and isinstance(CollisionChecker(arm), ClearanceChecker)


BELOW_TRIAL = {"records", "errors", "world", "sim", "tools", "control", "agents", "reasoners"}
#: The packages each package may import at run time (``TYPE_CHECKING`` imports aside).
#: Dependencies point one way: runs -> recording -> trial -> agents/control -> tools ->
#: sim/world, and the Gym env, the MCP server and the Inspect task reach the scene only
#: through the trial layer.
MAY_IMPORT: dict[str, set[str]] = {
    "records": set(),
    "errors": {"records"},
    "world": {"records", "errors"},
    "sim": {"records", "errors", "world"},
    "tools": {"records", "errors", "world"},
    "control": {"records", "errors", "world", "sim"},
    "agents": {"records", "errors", "world", "tools"},
    "reasoners": {"records", "errors", "world", "tools", "agents"},
    "trial": BELOW_TRIAL,
    "recording": BELOW_TRIAL | {"trial"},
    "runs": BELOW_TRIAL | {"trial", "recording"},
    "report": {"records", "errors", "world", "agents", "trial", "recording", "runs"},
    "gym_env": {"records", "errors", "world", "tools", "agents", "trial"},
    "mcp_server": {"records", "errors", "world", "tools", "agents", "trial"},
    # The Inspect task runs eval's trials with an LLMReasoner over Inspect's model
    # (reasoners), describes the agents' answer models and tools to it (agents, tools) and
    # gives the success rate the Wilson interval of runs/statistics.py (runs); nothing
    # imports it but Inspect, through its entry point.
    "inspect_task": {"records", "errors", "tools", "agents", "trial", "reasoners", "runs"},
    "export": {"errors", "trial", "recording", "runs", "report"},
    "__main__": {"cli"},
}
#: The command line, which wires every layer together, may import them all.
COMMAND = "cli"
PACKAGE = Path(__file__).resolve().parents[1] / "src" / "actionreasoning"


def _run_time_imports(tree: ast.Module) -> set[str]:
    """The ``actionreasoning`` subpackages a module imports outside ``if TYPE_CHECKING:``."""
    skipped = {
        id(node)
        for block in ast.walk(tree)
        if isinstance(block, ast.If) and ast.unparse(block.test) == "TYPE_CHECKING"
        for node in ast.walk(block)
    }
    names: set[str] = set()
    for node in ast.walk(tree):
        if id(node) in skipped:
            continue
        if isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
        elif isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
    return {n.split(".")[1] for n in names if n.startswith("actionreasoning.")}


def test_every_package_imports_only_the_layers_below_it() -> None:
    wrong = []
    for module in sorted(PACKAGE.rglob("*.py")):
        parts = module.relative_to(PACKAGE).parts
        package = parts[0] if len(parts) > 1 else module.stem
        if package in ("__init__", COMMAND):
            continue
        used = _run_time_imports(ast.parse(module.read_text())) - {package}
        wrong += [
            f"{module.relative_to(PACKAGE)} imports {u}" for u in sorted(used - MAY_IMPORT[package])
        ]
    assert not wrong, "\n".join(wrong)
