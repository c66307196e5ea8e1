# SPDX-License-Identifier: MIT
"""PNG files to and from numpy arrays: 8- or 16-bit grey, RGB and RGBA
written, 8-bit RGB and RGBA read.

Blender's Image.save() encodes one image at a time on one core, with zlib.
Here the pixel data is compressed and inflated natively (_native.zlib_compress
and png_pixels, through libdeflate, which releases the GIL), the images of a
job side by side. Reading, Blender hands out pixels only as floats, after
holding the image as its own buffer: decode_png skips both copies. No bpy in
this module.
"""

from __future__ import annotations

import io
import os
import struct
import zlib
from concurrent.futures import ThreadPoolExecutor
from typing import BinaryIO, Iterable, Optional, Tuple

import numpy as np

SIGNATURE = b"\x89PNG\r\n\x1a\n"
_UP_FILTER = 2  # each byte minus the byte above it, modulo 256 (PNG spec 9.2)
_LEVEL = 1  # the fastest: baked textures gain little from slower ones (bench/README.md)


def _write_chunk(out: BinaryIO, kind: bytes, data) -> None:
    """One chunk: length, type, data (any bytes-like object, written as it
    is: a large image's stream is not copied again) and CRC."""
    out.write(struct.pack(">I", len(data)) + kind)
    out.write(data)
    out.write(struct.pack(">I", zlib.crc32(data, zlib.crc32(kind)) & 0xFFFFFFFF))


_COLOUR_TYPE = {1: 0, 3: 2, 4: 6}  # channels -> PNG colour type: greyscale, truecolour, truecolour with alpha
_CHANNELS = {2: 3, 6: 4}  # the colour types decode_png reads -> channels
_IHDR = struct.Struct(">IIBBBBB")  # width, height, bit depth, colour type, compression, filter, interlace
HEADER_BYTES = 33  # signature, then the IHDR chunk: length, type, 13 bytes, CRC


def _scanlines(pixels: np.ndarray) -> np.ndarray:
    """(H, 1 + W C) filtered rows, top row first: each row starts with its
    filter type, Up: at the fastest deflate level it compresses baked
    textures nearly as well as slower levels, in a fraction of their time
    (bench/README.md)."""
    if pixels.dtype not in (np.uint8, np.uint16) or pixels.ndim != 3 or pixels.shape[2] not in _COLOUR_TYPE \
            or 0 in pixels.shape:
        raise ValueError(f"encode_png needs (H, W, 1, 3 or 4) uint8 or uint16 pixels, H and W >= 1 (PNG has no "
                         f"empty image), got {pixels.shape} {pixels.dtype}")
    height = pixels.shape[0]
    if pixels.dtype == np.uint16:  # PNG's samples are big-endian; its filters work on bytes
        pixels = pixels.astype(">u2").view(np.uint8)
    rows = pixels[::-1].reshape(height, -1)  # PNG rows run top down (a view, no copy)
    scanlines = np.empty((height, rows.shape[1] + 1), dtype=np.uint8)
    scanlines[:, 0] = _UP_FILTER
    np.subtract(rows[1:], rows[:-1], out=scanlines[1:, 1:])  # the first row has zeros above it
    scanlines[0, 1:] = rows[0]
    return scanlines


def _write_png(out: BinaryIO, pixels: np.ndarray, stream: np.ndarray) -> None:
    """The PNG of pixels whose rows compress to the zlib stream `stream`."""
    height, width, channels = pixels.shape
    header = _IHDR.pack(width, height, 8 * pixels.itemsize, _COLOUR_TYPE[channels], 0, 0, 0)  # no interlace
    out.write(SIGNATURE)
    _write_chunk(out, b"IHDR", header)
    _write_chunk(out, b"IDAT", memoryview(stream))
    _write_chunk(out, b"IEND", b"")


def _compressed_rows(pixels: np.ndarray) -> np.ndarray:
    from . import _native
    return _native.zlib_compress(_scanlines(pixels).reshape(-1), _LEVEL)


def encode_png(pixels: np.ndarray) -> bytes:
    """(H, W, 1, 3 or 4) uint8 or uint16 pixels, row 0 at the bottom as Blender stores them, as a PNG."""
    out = io.BytesIO()
    _write_png(out, pixels, _compressed_rows(pixels))
    return out.getvalue()


def write_pngs(files: Iterable[Tuple[str, np.ndarray]]) -> None:
    """Writes each (path, pixels) as encode_png does, the images compressed
    side by side, one thread per core. No file is opened before every image
    is compressed: pixels it cannot encode leave every path as it was."""
    files = list(files)
    workers = max(1, min(len(files), os.cpu_count() or 1))
    with ThreadPoolExecutor(max_workers=workers) as pool:
        streams = [pool.submit(_compressed_rows, pixels) for _, pixels in files]  # all queued first
        streams = [stream.result() for stream in streams]
    for (path, pixels), stream in zip(files, streams):
        with open(path, "wb") as f:
            _write_png(f, pixels, stream)


# --------------------------------------------------------------------------- reading
_LARGEST_SIDE = 2 ** 31 - 1  # PNG spec 11.2.2
# Deflate turns a byte into at most 1032 (its longest match, 258 bytes, costs
# at least 2 bits): a header claiming more pixels than its data could hold is
# refused before a buffer of that size is asked for.
_MAX_INFLATION = 1032
_IEND = b"\x00\x00\x00\x00IEND\xaeB`\x82"  # the whole IEND chunk, CRC included
TAIL_BYTES = len(_IEND)


def plain_png_size(head: bytes) -> Optional[Tuple[int, int, int]]:
    """(width, height, channels) when ``head`` (a file's first HEADER_BYTES
    bytes or more) starts a PNG that decode_png reads: 8-bit RGB or RGBA,
    not interlaced, with a sound IHDR chunk; None otherwise."""
    if len(head) < HEADER_BYTES or head[:8] != SIGNATURE or head[12:16] != b"IHDR":
        return None
    if struct.unpack(">I", head[8:12])[0] != 13 or not _crc_holds(head, 8, 13):
        return None
    width, height, depth, colour, compression, filtering, interlace = _IHDR.unpack(head[16:29])
    if depth != 8 or colour not in _CHANNELS or compression or filtering or interlace:
        return None
    if not (0 < width <= _LARGEST_SIDE and 0 < height <= _LARGEST_SIDE):
        return None
    return width, height, _CHANNELS[colour]


def file_ends(path: str, head: int, tail: int) -> Tuple[bytes, bytes]:
    """The first `head` and the last `tail` bytes of a file, without reading
    the rest (a large image or model need not be read to check its ends)."""
    with open(path, "rb") as f:
        first = f.read(head)
        f.seek(max(0, os.fstat(f.fileno()).st_size - tail))
        return first, f.read(tail)


def ends_whole(tail: bytes) -> bool:
    """Whether a file's last TAIL_BYTES bytes are a PNG's IEND chunk: a file
    cut short, the usual damage, ends otherwise."""
    return tail[-TAIL_BYTES:] == _IEND


def _crc_holds(data, pos: int, length: int) -> bool:
    """The CRC of the chunk of `length` data bytes whose length field is at pos."""
    stored = struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])[0]
    return zlib.crc32(data[pos + 4:pos + 8 + length]) & 0xFFFFFFFF == stored


def critical_crcs_hold(data: bytes) -> bool:
    """Whether every critical chunk of a PNG file's bytes (its type's first
    letter upper case: IHDR, PLTE, IDAT, IEND) passes its CRC, as libpng
    requires; ancillary chunks failing theirs libpng only drops."""
    pos, view = 8, memoryview(data)
    while pos + 12 <= len(data):
        length = struct.unpack(">I", data[pos:pos + 4])[0]
        if pos + 12 + length > len(data):
            return True  # cut short: the decoder says so
        if 65 <= data[pos + 4] <= 90 and not _crc_holds(view, pos, length):
            return False
        pos += 12 + length
    return True


def _image_data(data: bytes) -> bytes:
    """The joined IDAT chunks, their CRCs checked (libpng refuses a file whose
    critical chunks fail theirs, and Blender with it). A tRNS chunk (one
    colour made transparent) is refused: Blender turns it into alpha, which
    the rows do not hold."""
    pos, idat, view = 8, [], memoryview(data)  # views: the chunks are copied once, by the join
    while pos + 12 <= len(data):
        length = struct.unpack(">I", data[pos:pos + 4])[0]
        kind = data[pos + 4:pos + 8]
        if pos + 12 + length > len(data):
            raise ValueError("PNG chunk runs past the end of the file")
        if kind == b"IDAT":
            if not _crc_holds(view, pos, length):
                raise ValueError("PNG pixel data fails its CRC")
            idat.append(view[pos + 8:pos + 8 + length])
        elif kind == b"tRNS":
            raise ValueError("PNG with a tRNS chunk (colour-key transparency)")
        elif kind == b"IEND":
            return b"".join(idat)
        pos += 12 + length
    raise ValueError("PNG ends before its IEND chunk")


def decode_png(data: bytes) -> np.ndarray:
    """(H, W, C) uint8 pixels, C the file's channels (3 or 4), row 0 at the
    bottom as Blender stores them, of a PNG file's bytes that plain_png_size
    accepts. ValueError for any other file, a tRNS chunk, a failed CRC, a
    header claiming more pixels than the data holds, or a broken zlib stream
    (its Adler-32 checks the pixel bytes); MemoryError when the pixels do not
    fit in memory."""
    size = plain_png_size(data[:HEADER_BYTES])
    if size is None:
        raise ValueError("not an 8-bit, non-interlaced RGB or RGBA PNG")
    from . import _native

    width, height, channels = size
    expected = height * (1 + width * channels)
    compressed = _image_data(data)
    if expected > _MAX_INFLATION * len(compressed) + 1024:
        raise ValueError(f"PNG header claims {width}x{height} pixels, more than its data holds")
    try:
        return _native.png_pixels(compressed, width, height, channels)
    except ValueError as exc:
        raise ValueError(f"PNG pixel data is broken: {exc}") from exc


def decode_png_or_none(data: Optional[bytes]) -> Optional[np.ndarray]:
    """decode_png's pixels, or None when there are no bytes or they are no PNG
    it decodes (another format, a tRNS chunk, a broken file): the caller's
    other reader then reads them, or says why not. MemoryError passes: the
    other reader would need more."""
    try:
        return None if data is None else decode_png(data)
    except ValueError:
        return None
