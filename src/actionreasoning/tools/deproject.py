"""Deprojection: the world point a camera's depth picture shows at a pixel.

A measurement of the call's own pictures, not of a brick: it reads the depth picture the
agent was sent, at the pixel asked, and turns it into a world point by the pinhole formula
of the prompt's Cameras section (``world/cameras.py``). The image tier's check tools.
"""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field

from actionreasoning.errors import ToolError
from actionreasoning.tools.base import ToolContext, ToolModel, tool
from actionreasoning.world.geometry import Vec3
from actionreasoning.world.pictures import CAMERAS, PictureKind, read_depth

#: The cameras that send a depth picture.
DepthCamera = Literal["top_down", "pick_side"]


class PixelQuery(ToolModel):
    """A pixel of one of the call's depth pictures: column u and row v (from the top-left
    pixel's centre), rounded to the nearest pixel."""

    camera: DepthCamera
    u: float = Field(ge=-0.5, description="Column, rightwards.")
    v: float = Field(ge=-0.5, description="Row, downwards.")


class PixelPoint(ToolModel):
    """What the depth picture shows at the pixel: its depth along the camera's optical axis
    and the world point there; both null where the picture has no reading."""

    u: int = Field(description="The pixel read: column.")
    v: int = Field(description="The pixel read: row.")
    depth_m: float | None
    point_m: Vec3 | None


def deproject(context: ToolContext, query: PixelQuery) -> PixelPoint:
    """The world point under a pixel of this call's depth picture of ``camera``: p = R ((u -
    cx) / fx * d, (v - cy) / fy * d, d) + t, at the pixel's depth d."""
    camera = CAMERAS[query.camera]
    picture = next(
        (p for p in context.pictures if p.camera == query.camera and p.kind is PictureKind.DEPTH),
        None,
    )
    if picture is None:
        raise ToolError(f"this call carries no depth picture of {query.camera}")
    u, v = round(query.u), round(query.v)
    if u >= camera.width or v >= camera.height:
        raise ToolError(
            f"pixel ({u}, {v}) is outside {query.camera}'s {camera.width} x {camera.height}"
        )
    depth = float(read_depth(picture.png)[v, u])
    if math.isnan(depth):
        return PixelPoint(u=u, v=v, depth_m=None, point_m=None)
    return PixelPoint(u=u, v=v, depth_m=depth, point_m=camera.deproject(u, v, depth))


DEPROJECT = tool("deproject", deproject)
