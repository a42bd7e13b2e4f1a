"""The MCP server ``actionreasoning mcp`` (the ``mcp`` extra): one trial at a time for an
outside agent, over stdio. ``door.py`` holds the tools, ``server.py`` the protocol."""

from __future__ import annotations

try:
    import mcp  # noqa: F401
except ImportError as error:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "the MCP server needs the MCP SDK: pip install 'actionreasoning[mcp]'"
    ) from error

from actionreasoning.mcp_server.server import serve

__all__ = ["serve"]
