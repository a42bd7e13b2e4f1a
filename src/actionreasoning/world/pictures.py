"""Pictures as an agent is sent them: a camera's colour or depth image as PNG bytes.

Colour is 8-bit RGB. Depth is one 16-bit channel in :data:`DEPTH_UNIT_M` steps along the
camera's optical axis (its z, see :mod:`~actionreasoning.world.cameras`), so a count of
12345 is 1.2345 m; 0 is no reading. Both encode losslessly and the same array gives the same
bytes, so a picture is named by its content hash.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import io
from dataclasses import dataclass
from enum import StrEnum

import numpy as np
from PIL import Image

from actionreasoning.world.cameras import OVERVIEW, PICK_SIDE, TOP_DOWN, Camera

#: One count of a depth image (m): 0.1 mm, a hundredth of the success rule's 2 cm and up to
#: 6.5535 m, beyond the renderer's far plane.
DEPTH_UNIT_M = 1e-4
_MAX_COUNT = np.iinfo(np.uint16).max
MEDIA_TYPE = "image/png"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class PictureKind(StrEnum):
    """What a picture shows."""

    COLOUR = "colour"
    DEPTH = "depth"


#: The pictures of the image tier, in the order a prompt carries them: the overview in
#: colour, and the top-down and pick-side cameras in colour and depth.
SHOWN: tuple[tuple[Camera, tuple[PictureKind, ...]], ...] = (
    (OVERVIEW, (PictureKind.COLOUR,)),
    (TOP_DOWN, (PictureKind.COLOUR, PictureKind.DEPTH)),
    (PICK_SIDE, (PictureKind.COLOUR, PictureKind.DEPTH)),
)
CAMERAS: dict[str, Camera] = {camera.name: camera for camera, _ in SHOWN}


def picture_name(camera: str, kind: PictureKind) -> str:
    """How prompts, transcripts and observations name a picture, e.g. ``top_down.depth``."""
    return f"{camera}.{kind}"


#: The names of SHOWN's pictures, in its order.
SHOWN_NAMES: tuple[str, ...] = tuple(
    picture_name(camera.name, kind) for camera, kinds in SHOWN for kind in kinds
)


@dataclass(frozen=True)
class Picture:
    """One camera's colour or depth image, PNG-encoded."""

    camera: str
    kind: PictureKind
    png: bytes

    @property
    def name(self) -> str:
        """How prompts and transcripts name it (:func:`picture_name`)."""
        return picture_name(self.camera, self.kind)

    @property
    def sha256(self) -> str:
        """The hash of its bytes: a recording stores it once under this name."""
        return hashlib.sha256(self.png).hexdigest()

    @property
    def data_url(self) -> str:
        """A ``data:`` URL of it, as chat image parts carry images."""
        return f"data:{MEDIA_TYPE};base64,{base64.b64encode(self.png).decode()}"


def png_of(url: str) -> bytes | None:
    """The bytes of a base64 PNG ``data:`` URL (:attr:`Picture.data_url`'s inverse); None
    for any other URL, bad base64 or bytes that are no PNG."""
    head, _, data = url.partition(",")
    if head != f"data:{MEDIA_TYPE};base64":
        return None
    try:
        png = base64.b64decode(data, validate=True)
    except binascii.Error:
        return None
    return png if png.startswith(PNG_SIGNATURE) else None


def colour_png(rgb: np.ndarray) -> bytes:
    """PNG bytes of an RGB image (height x width x 3, uint8)."""
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"a colour image is h x w x 3 uint8, not {rgb.shape} {rgb.dtype}")
    return _png(Image.fromarray(rgb))


def depth_png(depth_m: np.ndarray) -> bytes:
    """PNG bytes of a depth image (height x width, m): 16-bit counts of DEPTH_UNIT_M, the
    nearest count; beyond the range or not finite is 0, no reading."""
    counts = np.rint(np.asarray(depth_m, dtype=np.float64) / DEPTH_UNIT_M)
    counts[~np.isfinite(counts) | (counts > _MAX_COUNT) | (counts < 0)] = 0
    return _png(Image.fromarray(counts.astype(np.uint16)))


def read_colour(png: bytes) -> np.ndarray:
    """The RGB array (uint8) of a colour picture's PNG bytes."""
    with Image.open(io.BytesIO(png)) as image:
        return np.asarray(image.convert("RGB"))


def read_depth(png: bytes) -> np.ndarray:
    """The depth (m, float32; NaN where there is no reading) of a depth picture's PNG bytes."""
    with Image.open(io.BytesIO(png)) as image:
        counts = np.asarray(image, dtype=np.float64)
    if counts.ndim != 2:
        raise ValueError(f"a depth picture has one channel, not shape {counts.shape}")
    depth = counts * DEPTH_UNIT_M
    depth[counts == 0] = np.nan
    return depth.astype(np.float32)


def _png(image: Image.Image) -> bytes:
    sink = io.BytesIO()
    image.save(sink, format="PNG", optimize=False, compress_level=6)
    return sink.getvalue()
