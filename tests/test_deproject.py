"""The check tier's deproject tool: the world point under a pixel of the call's own depth
picture, by the pinhole formula computed here by hand; no reading, a pixel off the
picture, or a call without pictures, each said."""

from __future__ import annotations

import numpy as np
import pytest

from actionreasoning.errors import ToolError
from actionreasoning.tools.base import ToolContext
from actionreasoning.tools.deproject import DEPROJECT, PixelQuery
from actionreasoning.world.cameras import TOP_DOWN
from actionreasoning.world.pictures import Picture, PictureKind, depth_png


def context(pictures: tuple[Picture, ...]) -> ToolContext:
    """A tool context with ``pictures``: deproject reads nothing else."""
    return ToolContext(state=None, arm=None, collisions=None, pictures=pictures)  # type: ignore[arg-type]


def test_a_pixel_and_its_depth_give_the_world_point_by_hand() -> None:
    """The top-down camera looks straight down from (0.05, -0.1, 1.8), the image's top
    towards +y and its right towards +x, fx = fy = 768 px, principal point (319.5, 319.5):
    (419.6, 219.4) reads pixel (420, 219), 100.5 px right of and above the centre, so at
    depth 1.74 m the point (0.05 + 100.5 / 768 * 1.74, -0.1 + 100.5 / 768 * 1.74, 0.06)."""
    depth = np.full((TOP_DOWN.height, TOP_DOWN.width), 1.74)
    pictures = (Picture("top_down", PictureKind.DEPTH, depth_png(depth)),)
    point = DEPROJECT(context(pictures), PixelQuery(camera="top_down", u=419.6, v=219.4))
    assert (point.u, point.v, point.depth_m) == (420, 219, pytest.approx(1.74, abs=1e-4))
    run = 1.74 / TOP_DOWN.fx
    assert TOP_DOWN.fx == pytest.approx(768.0) and TOP_DOWN.cx == 319.5
    expected = (0.05 + 100.5 * run, -0.1 + 100.5 * run, 1.8 - 1.74)
    assert point.point_m == pytest.approx(expected, abs=1e-4)


def test_no_reading_off_the_picture_and_no_picture_are_said() -> None:
    depth = np.zeros((TOP_DOWN.height, TOP_DOWN.width))
    pictures = (Picture("top_down", PictureKind.DEPTH, depth_png(depth)),)
    empty = DEPROJECT(context(pictures), PixelQuery(camera="top_down", u=3, v=4))
    assert (empty.depth_m, empty.point_m) == (None, None)
    with pytest.raises(ToolError, match=r"pixel \(640, 4\) is outside top_down's 640 x 640"):
        DEPROJECT(context(pictures), PixelQuery(camera="top_down", u=640, v=4))
    with pytest.raises(ToolError, match="this call carries no depth picture of pick_side"):
        DEPROJECT(context(pictures), PixelQuery(camera="pick_side", u=3, v=4))
