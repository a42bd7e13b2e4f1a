"""Prompt rendering: <S_t, M_t, R_i, K_i, Gamma_i, Omega_i> through a template file.

The template is rendered with Jinja's StrictUndefined, so a missing variable is an error,
never an empty hole in a prompt. The state is the agent's :class:`StateView`; numbers are
rounded to 0.01 mm / 1e-5 so that prompts stay short without losing what the gates
measure. Tools and the answer are described field by field (``schema_text.py``).
"""

from __future__ import annotations

import json
import re
from functools import cache
from importlib import resources
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined

from actionreasoning.agents.knowledge import formula_text
from actionreasoning.agents.memory import TaskMemory
from actionreasoning.agents.observation import Observation
from actionreasoning.agents.schema_text import describe_fields
from actionreasoning.agents.spec import AgentSpec
from actionreasoning.agents.tiers import TIER_HELP
from actionreasoning.agents.view import Scope, StateView
from actionreasoning.tools.registry import TOOLS
from actionreasoning.world.geometry import round_floats
from actionreasoning.world.pictures import SHOWN, SHOWN_NAMES
from actionreasoning.world.tolerances import Tolerances

DIGITS = 5
_ENVIRONMENT = Environment(
    loader=PackageLoader("actionreasoning.agents", "prompts"),
    undefined=StrictUndefined,
    keep_trailing_newline=True,
    autoescape=False,
)
#: Where the state and the memory sit in a prompt (the reference model reads them back).
STATE_HEADING = "## State S_t"
MEMORY_HEADING = "## Memory M_t"
THRESHOLDS_HEADING = "## Thresholds"


def shown_json(data: Any) -> Any:
    """JSON data as prompts show it: floats rounded to ``DIGITS`` decimals, a whole one as an
    integer (0.0 as 0: the same number, read back)."""
    return _whole(round_floats(data, DIGITS))


def compact_json(data: Any) -> str:
    """Compact JSON of ``data`` as prompts show it (:func:`shown_json`)."""
    return json.dumps(shown_json(data), separators=(",", ":"))


def _whole(value: Any) -> Any:
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, list):
        return [_whole(v) for v in value]
    if isinstance(value, dict):
        return {k: _whole(v) for k, v in value.items()}
    return value


@cache
def _text(name: str) -> str:
    return resources.files("actionreasoning.agents").joinpath(f"prompts/{name}").read_text()


def conventions(frames: bool, view: StateView | None = None) -> str:
    """Units and formats, if ``frames`` the brick and tool frames with a worked example, and
    the site's notes where ``view`` shows a site beyond the paper's (:func:`site_notes`)."""
    text = _text("conventions.md") + (_text("frames.md") if frames else "")
    return text + (site_notes(view) if view is not None else "")


def site_notes(view: StateView) -> str:
    """What a site of several brick sizes or a pallet or feeder supply adds to the
    conventions: how sizes match, how a supply hands out bricks, how to read what is built.
    Empty for the paper's patterns (one size, scattered), whose prompts stay as they were."""
    sizes = any(t.size_m is not None for t in view.targets)
    if not sizes and view.supply is None:
        return ""
    template = _ENVIRONMENT.get_template("site.md.j2")
    return template.render(sizes=sizes, supply=view.supply)


def thresholds_text(tolerances: Tolerances, names: tuple[str, ...]) -> str:
    """The thresholds ``names``, a line each: ``- name = value: what it bounds`` (the role
    and gate text say which gate compares it; the single agent, which nothing checks, reads
    them as design values)."""
    values, fields = tolerances.model_dump(), Tolerances.model_fields
    return "\n".join(f"- {name} = {values[name]:g}: {fields[name].description}" for name in names)


#: One line of :func:`thresholds_text`: name, value, description.
THRESHOLD_LINE = re.compile(r"^- ([a-z_]+) = (\S+): (.+)$", re.M)


def _unread(spec: AgentSpec) -> set[str]:
    """Memory fields an agent's decision does not need: the step, which is the agent itself
    (the single agent reads it), and the bricks placed, for agents 2-6 (their state view
    marks placed bricks)."""
    if spec.scope is Scope.ALL:
        return set()
    return {"step"} if spec.scope is Scope.PICK else {"step", "placed"}


def state_blocks(
    spec: AgentSpec, view: StateView, memory: TaskMemory
) -> tuple[dict[str, Any], dict[str, Any]]:
    """The state S_t and the memory M_t as agent ``spec``'s prompt shows them, as JSON data
    (:func:`shown_json`): the prompt writes them, the MCP server's read_state returns them."""
    state = view.model_dump(
        mode="json", exclude_none=True, exclude=None if spec.observation.poses else {"bricks"}
    )
    shown = memory.model_dump(mode="json", exclude_defaults=True, exclude=_unread(spec))
    return shown_json(state), shown_json(shown)


@cache
def cameras_text(observation: Observation) -> str:
    """The Cameras section of a prompt whose call carries pictures: what the agent observes,
    which pictures in which order, how depth is encoded, each camera's intrinsics and pose,
    and how a pixel and its depth give a world point."""
    cameras = [
        camera.model_dump(mode="json") | {"pictures": list(kinds)} for camera, kinds in SHOWN
    ]
    template = _ENVIRONMENT.get_template("cameras.md.j2")
    return template.render(
        observation=observation, names=SHOWN_NAMES, cameras_json=compact_json(cameras)
    )


def render_prompt(
    spec: AgentSpec, view: StateView, memory: TaskMemory, tolerances: Tolerances
) -> str:
    """The full prompt of agent ``spec`` for this view of the state and this memory; with a
    Cameras section if the agent observes pictures."""
    template = _ENVIRONMENT.get_template("agent.md.j2")
    state, shown_memory = state_blocks(spec, view, memory)
    tools = [
        {
            "name": name,
            "description": TOOLS[name].description,
            "arguments": "\n".join(describe_fields(TOOLS[name].input_model)),
            "result": "\n".join(describe_fields(TOOLS[name].output_model)),
        }
        for name in spec.tools
    ]
    return template.render(
        number=spec.number,
        name=spec.name,
        conventions=conventions(spec.frames, view),
        role=spec.role,
        gate=spec.gate,
        state_json=compact_json(state),
        cameras=cameras_text(spec.observation) if spec.observation.pictures else "",
        memory_json=compact_json(shown_memory),
        thresholds=thresholds_text(tolerances, spec.thresholds),
        tier=spec.tier,
        tier_help=TIER_HELP[spec.tier],
        tools=tools,
        formulas=[formula_text(name) for name in spec.formulas],
        # How to correct by refusals, once there is one to correct by.
        thinking=(*spec.thinking, *(spec.feedback if memory.refusals else ())),
        answer_fields="\n".join(describe_fields(spec.output_model)),
    )
