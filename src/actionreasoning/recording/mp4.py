"""Whether an MP4 file is whole: read by the film process after encoding, and by `report`
before it copies a video. Free of the simulator and of the encoder."""

from __future__ import annotations

import struct
from pathlib import Path


class Unfinished(Exception):
    """The MP4 could not be written whole; the message says why, in one line."""


def check_mp4(path: str) -> None:
    """Refuse (:class:`Unfinished`) an MP4 that is not whole: its top-level boxes must fill
    the file exactly, and hold the file type, the movie header and the media data."""
    size = Path(path).stat().st_size
    kinds: set[bytes] = set()
    with open(path, "rb") as handle:
        offset = 0
        while offset < size:
            handle.seek(offset)
            head = handle.read(16)
            if len(head) < 8:
                raise Unfinished(f"cut short at {size} bytes, inside a box header")
            length, kind = struct.unpack(">I4s", head[:8])
            if length == 1 and len(head) == 16:
                length = struct.unpack(">Q", head[8:])[0]
            elif length == 0:  # the box runs to the end of the file
                length = size - offset
            if length < 8 or offset + length > size:
                name = kind.decode("latin-1")
                raise Unfinished(f"cut short at {size} bytes, inside its {name!r} box")
            kinds.add(kind)
            offset += length
    missing = sorted(k.decode() for k in {b"ftyp", b"moov", b"mdat"} - kinds)
    if missing:
        raise Unfinished(f"cut short at {size} bytes: no {', '.join(missing)} box")
