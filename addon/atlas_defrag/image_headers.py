# SPDX-License-Identifier: MIT
"""The pixel size an image file claims, read from its header alone.

Blender decodes a whole image to answer even Image.size, and a header can
claim far more pixels than its file holds (a few hundred bytes of JPEG may
claim 60000 x 60000). Reading the claim first lets the add-on refuse such an
image before Blender allocates it: past 2^31 pixel values Blender 3.4 crashes
and bpy 4.5 wraps the pixel count. PNG, JPEG, TIFF, BMP, OpenEXR and TGA
(known by its file name: it has no signature) are read; for other formats
the claim is unknown (None) and Blender is left to decode them. No bpy here.
"""

from __future__ import annotations

import os
import struct
from typing import BinaryIO, NamedTuple, Optional


class Claim(NamedTuple):
    width: int
    height: int
    float_pixels: bool  # Blender holds the pixels as floats (OpenEXR), not bytes


# JPEG start-of-frame markers (ITU T.81 table B.1): C0-CF but DHT (C4), JPG (C8) and DAC (CC).
_JPEG_FRAMES = set(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers that stand alone, without a length: TEM, RST0-7 and SOI.
_JPEG_BARE = {0x01, *range(0xD0, 0xD9)}
# A JPEG whose frame header is not among its first this many segments is taken as unknown.
_JPEG_MAX_SEGMENTS = 256
_EXR_MAX_ATTRIBUTES = 256


def claimed_size(f: BinaryIO, file_name: str = "") -> Optional[Claim]:
    """The (width, height) f's header claims, f positioned at the file's
    start; None when the format is not one read here or the header is cut
    short or malformed (Blender then decides)."""
    head = f.read(32)
    try:
        if head.startswith(b"\x89PNG\r\n\x1a\n") and head[12:16] == b"IHDR":
            return Claim(*struct.unpack(">II", head[16:24]), False)
        if head.startswith(b"\xff\xd8"):
            return _jpeg(f)
        if head[:4] in (b"II*\x00", b"MM\x00*"):
            return _tiff(f, "<" if head[:2] == b"II" else ">")
        if head.startswith(b"BM"):
            width, height = struct.unpack("<ii", head[18:26])
            return Claim(abs(width), abs(height), False)  # negative height: rows stored top down
        if head.startswith(b"\x76\x2f\x31\x01"):
            return _exr(f)
        if file_name.lower().endswith((".tga", ".targa")):
            return Claim(*struct.unpack("<HH", head[12:16]), False)
    except (struct.error, ValueError, OSError):  # a header cut short, or an offset off the file
        return None
    return None


def _jpeg(f: BinaryIO) -> Optional[Claim]:
    """Walks the segments after SOI to the frame header: length(2), precision(1), height(2), width(2)."""
    f.seek(2)
    for _ in range(_JPEG_MAX_SEGMENTS):
        if f.read(1) != b"\xff":
            return None
        marker = f.read(1)
        while marker == b"\xff":  # fill bytes may pad a marker
            marker = f.read(1)
        if not marker or marker[0] in (0xD9, 0xDA):  # the end, or scan data before any frame header
            return None
        if marker[0] in _JPEG_BARE:
            continue
        length, = struct.unpack(">H", f.read(2))
        if marker[0] in _JPEG_FRAMES:
            height, width = struct.unpack(">xHH", f.read(5))
            return Claim(width, height, False)
        f.seek(length - 2, os.SEEK_CUR)
    return None


def _tiff(f: BinaryIO, order: str) -> Optional[Claim]:
    """ImageWidth (256) and ImageLength (257) of the first image file directory."""
    f.seek(4)
    offset, = struct.unpack(order + "I", f.read(4))
    f.seek(offset)
    count, = struct.unpack(order + "H", f.read(2))
    size = {}
    for _ in range(count):
        tag, kind, _n, value = struct.unpack(order + "HHI4s", f.read(12))
        if tag in (256, 257):
            size[tag] = struct.unpack(order + ("H" if kind == 3 else "I"), value[:2 if kind == 3 else 4])[0]
    return Claim(size[256], size[257], False) if len(size) == 2 else None


def _exr(f: BinaryIO) -> Optional[Claim]:
    """The dataWindow attribute (box2i: x min, y min, x max, y max) of the
    header's name, type, size, value records."""
    f.seek(8)
    for _ in range(_EXR_MAX_ATTRIBUTES):
        name, kind = _c_string(f), _c_string(f)
        if not name:
            return None
        size, = struct.unpack("<i", f.read(4))
        if name == b"dataWindow" and kind == b"box2i":
            x0, y0, x1, y1 = struct.unpack("<iiii", f.read(16))
            return Claim(x1 - x0 + 1, y1 - y0 + 1, True)
        f.seek(size, os.SEEK_CUR)
    return None


def _c_string(f: BinaryIO, limit: int = 256) -> bytes:
    """Bytes up to a NUL (EXR names are at most 255 bytes)."""
    out = bytearray()
    while len(out) < limit:
        c = f.read(1)
        if not c or c == b"\x00":
            break
        out += c
    return bytes(out)


def physical_memory() -> Optional[int]:
    """This machine's memory in bytes; None where sysconf cannot tell (Windows)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
