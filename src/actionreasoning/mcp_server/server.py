"""The door's tools over the Model Context Protocol (the official SDK's low-level server,
stdio transport).

The SDK serves the protocol on the process's stdout and, while it serves, points file
descriptor 1 at stderr, so nothing the simulator or a library prints can reach the wire.
Every call runs in a worker thread (a trial's answer moves the arm for seconds), after
every call that arrived before it (:mod:`arrivals`), and comes back as a tool result: its
JSON as text and as structured content, of the output schema its tool is listed with,
``isError`` set when it was refused, and the waiting agent's pictures as PNG image content
after the text when the trial observes them. A refusal is never a protocol error.

The SDK reads stdin through :mod:`wire`, which answers every line the SDK would drop
(not JSON, not a JSON-RPC message, over ``MAX_MESSAGE_BYTES``) with a JSON-RPC error.
"""

from __future__ import annotations

import base64
import json
from typing import Any

import anyio
import anyio.to_thread
import mcp_types as types
from mcp.server import Server, ServerRequestContext

from actionreasoning import __version__
from actionreasoning.mcp_server.arrivals import Arrivals
from actionreasoning.mcp_server.door import Door
from actionreasoning.mcp_server.wire import stdio
from actionreasoning.world.pictures import MEDIA_TYPE

INSTRUCTIONS = """\
Build a brick pattern with a robot arm by answering its six gated agents (pre_grasp,
descent, grasp, lift, placement, release), one request at a time. start_trial starts a trial
(pattern, physics, noise, seed, trial). read_state shows the waiting agent: its prompt (role,
measured state, memory, thresholds, tools, answer format), its state and memory blocks as
JSON, its tools and its answer schema. Call that agent's tools and, for any agent, the
gates' measurements (slip_estimate, alignment_errors, reachability), then submit_answer
with its answer.
Every answer is validated and checked by the agent's gate before the arm moves; a refused
one comes back with a typed refusal or the gate's feedback, and the arm stays where it was.
When a reply's result is set the trial has ended; finish_trial returns its results line and
closes it. One trial per connection: start_trial again abandons the one running."""


def build(door: Door, arrivals: Arrivals) -> Server[Any]:
    """A server whose tools are ``door``'s, each call run in its turn among ``arrivals``."""
    tools = [
        types.Tool(
            name=entry.name,
            description=entry.description,
            input_schema=entry.input_schema,
            output_schema=entry.output_schema,
        )
        for entry in door.tools()
    ]

    async def list_tools(
        ctx: ServerRequestContext[Any], params: types.PaginatedRequestParams | None
    ) -> types.ListToolsResult:
        return types.ListToolsResult(tools=tools)

    async def call_tool(
        ctx: ServerRequestContext[Any], params: types.CallToolRequestParams
    ) -> types.CallToolResult:
        async with arrivals.turn(ctx.request_id) as sent:
            name, arguments = sent or (params.name, params.arguments)
            reply = await anyio.to_thread.run_sync(door.call, name, arguments)
        images = [
            types.ImageContent(data=base64.b64encode(p.png).decode(), mime_type=MEDIA_TYPE)
            for p in reply.pictures
        ]
        return types.CallToolResult(
            content=[types.TextContent(text=json.dumps(reply.data)), *images],
            structured_content=reply.data,
            is_error=reply.refused,
        )

    return Server(
        "actionreasoning",
        version=__version__,
        instructions=INSTRUCTIONS,
        on_list_tools=list_tools,
        on_call_tool=call_tool,
    )


def serve() -> None:
    """Serve one connection over stdio until the client closes it; end its trial then."""
    anyio.run(_serve)


async def _serve() -> None:
    door, arrivals = Door(), Arrivals()
    try:
        async with stdio(arrivals) as (read_stream, write_stream):
            server = build(door, arrivals)
            await server.run(read_stream, write_stream, server.create_initialization_options())
    finally:
        door.close()
