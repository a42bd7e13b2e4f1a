"""What a tool is: a name, a description, typed input and output models, and a function.

Tools read the world only through a :class:`ToolContext` (the measured WorldState plus the
arm's kinematic model and collision checker, as the protocols of ``ports.py``), so a tool
call by an LLM and one by Python code see the same thing.
The agents' prompts describe every tool's arguments and result field by field.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar, get_type_hints

from pydantic import BaseModel, ConfigDict

from actionreasoning.tools.ports import ArmModel, ClearanceChecker
from actionreasoning.world.models import WorldState
from actionreasoning.world.pictures import Picture

In = TypeVar("In", bound=BaseModel)
Out = TypeVar("Out", bound=BaseModel)


class ToolModel(BaseModel):
    """Base of every tool input and output: frozen, no unknown fields."""

    model_config = ConfigDict(frozen=True, extra="forbid")


@dataclass(frozen=True)
class ToolContext:
    """What a tool may look at: the measured world, the arm's kinematic model and its
    collision checker (both on the kinematic copy, never on the simulation), and the
    pictures the agent's call carries (none without pictures)."""

    state: WorldState
    arm: ArmModel
    collisions: ClearanceChecker
    pictures: tuple[Picture, ...] = ()


@dataclass(frozen=True)
class Tool(Generic[In, Out]):
    """A callable piece of knowledge with typed, described input and output."""

    name: str
    description: str
    input_model: type[In]
    output_model: type[Out]
    function: Callable[[ToolContext, In], Out]

    def __call__(self, context: ToolContext, arguments: In) -> Out:
        """Run the tool on already validated arguments."""
        return self.function(context, arguments)


def tool(name: str, function: Callable[[ToolContext, In], Out]) -> Tool[In, Out]:
    """A tool from a typed function ``(context, arguments) -> output``: its input and output
    models come from the type hints, its description from the docstring."""
    hints = get_type_hints(function)
    arguments = [hint for key, hint in hints.items() if key != "return"][1]
    return Tool(
        name=name,
        description=function.__doc__ or "",
        input_model=arguments,
        output_model=hints["return"],
        function=function,
    )
