# SPDX-License-Identifier: MIT
"""The pixel size an image file claims, read from its header alone.

Blender decodes a whole image to answer even Image.size, and a header can
claim far more pixels than its file holds (a few hundred bytes of JPEG may
claim 60000 x 60000). Reading the claim first lets the add-on refuse such an
image before Blender allocates it: past 2^31 pixel values Blender 3.4 crashes
and bpy 4.5 wraps the pixel count. Every still format Blender reads is read
here: PNG, JPEG, JPEG 2000, TIFF, BMP, OpenEXR, Radiance HDR, Iris, DDS, PSD,
WebP, DPX, Cineon, and TGA (known by its file name: it has no signature).
No bpy here.
"""

from __future__ import annotations

import os
import re
import struct
from typing import BinaryIO, NamedTuple, Optional


class Claim(NamedTuple):
    width: int
    height: int
    float_pixels: bool  # Blender holds the pixels as floats (OpenEXR, HDR, 16-bit files), not bytes
    # The format packs at most _MAX_PIXELS_PER_BYTE pixels into a byte of its
    # file; lossless WebP, JPEG 2000, TIFF and OpenEXR may pack a flat image tighter.
    bounded: bool = True


# JPEG start-of-frame markers (ITU T.81 table B.1): C0-CF but DHT (C4), JPG (C8) and DAC (CC).
_JPEG_FRAMES = set(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
# Markers that stand alone, without a length: TEM, RST0-7 and SOI.
_JPEG_BARE = {0x01, *range(0xD0, 0xD9)}
# Segments walked before a frame header or scan is given up on: real files
# hold tens; a forged one of millions of empty segments would take minutes.
_JPEG_MAX_SEGMENTS = 1 << 16
_EXR_MAX_ATTRIBUTES = 1024
# Radiance's resolution line, e.g. "-Y 1024 +X 2048": rows first when Y comes first.
_HDR_SIZE = re.compile(rb"^[-+]([XY]) (\d+) [-+]([XY]) (\d+)$")
_HDR_MAX_LINES, _HDR_MAX_LINE = 1024, 4096


def claimed_size(f: BinaryIO, file_name: str = "") -> Optional[Claim]:
    """The (width, height) f's header claims, f positioned at the file's
    start; None when it is no format read here or its header is cut short or
    malformed."""
    head = f.read(1024)
    try:
        reader = _reader(head, file_name)
        return reader(f, head) if reader is not None else None
    except (struct.error, ValueError, OSError):  # a header cut short, or an offset off the file
        return None


def _reader(head: bytes, file_name: str):
    """The reader of head's format, by its signature; None if none matches."""
    for signature, reader in _SIGNATURES:
        if head.startswith(signature):
            return reader
    if file_name.lower().endswith((".tga", ".targa")) or _looks_like_tga(head):
        return lambda f, h: Claim(*struct.unpack("<HH", h[12:16]), False)
    return None


def _looks_like_tga(head: bytes) -> bool:
    """TGA has no signature: Blender takes a file for one by its colour-map
    type, image type and pixel depth; so does this."""
    return (len(head) >= 18 and head[1] in (0, 1) and head[2] in (1, 2, 3, 9, 10, 11)
            and head[16] in (8, 15, 16, 24, 32))


def _png(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """IHDR: width, height, bit depth (16: Blender holds floats)."""
    return Claim(*struct.unpack(">II", head[16:24]), head[24] == 16) if head[12:16] == b"IHDR" else None


def _jpeg(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """The frame header: length(2), precision(1), height(2), width(2)."""
    for marker in _jpeg_markers(f):
        if marker in _JPEG_FRAMES:
            height, width = struct.unpack(">xHH", f.read(5))
            return Claim(width, height, False)
        if marker == 0xDA:  # scan data before any frame header
            return None
    return None


def _jpeg_markers(f: BinaryIO):
    """The markers of the segments after SOI, f left after each one's length
    (the caller may read the segment; the walk skips it). Bytes other than
    0xFF between segments are skipped, as libjpeg skips them."""
    f.seek(2)
    for _ in range(_JPEG_MAX_SEGMENTS):
        if not _to_next_ff(f):
            return
        marker = f.read(1)
        while marker == b"\xff":  # fill bytes may pad a marker
            marker = f.read(1)
        if not marker or marker[0] == 0xD9:
            return
        if marker[0] in _JPEG_BARE or marker[0] == 0:
            continue
        raw = f.read(2)
        if len(raw) < 2:  # the file ends inside the segment's length
            return
        length, = struct.unpack(">H", raw)
        start = f.tell()
        yield marker[0]
        f.seek(start + length - 2)


def _to_next_ff(f: BinaryIO, chunk: int = 4096) -> bool:
    """Moves f just past its next 0xFF byte (most often the next one); False at the end of the file."""
    byte = f.read(1)
    while byte and byte != b"\xff":
        data = f.read(chunk)
        at = data.find(b"\xff")
        if at >= 0:
            f.seek(at + 1 - len(data), os.SEEK_CUR)
            return True
        byte = data[-1:]
    return byte == b"\xff"


def _tiff(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """ImageWidth (256), ImageLength (257) and BitsPerSample (258) of the
    first image file directory; BigTIFF's directory has 8-byte counts and
    values."""
    order = "<" if head[:2] == b"II" else ">"
    big = head[2:4] in (b"+\x00", b"\x00+")
    f.seek(8 if big else 4)
    offset, = struct.unpack(order + ("Q" if big else "I"), f.read(8 if big else 4))
    f.seek(offset)
    count, = struct.unpack(order + ("Q" if big else "H"), f.read(8 if big else 2))
    entry = struct.Struct(order + ("HHQ8s" if big else "HHI4s"))
    size = {}
    for _ in range(min(count, 4096)):
        tag, kind, n, value = entry.unpack(f.read(entry.size))
        if tag in (256, 257, 258):
            code = {3: "H", 4: "I", 16: "Q"}.get(kind, "I")
            if n * struct.calcsize(code) > len(value):  # BitsPerSample per channel: the values lie elsewhere
                at = f.tell()
                f.seek(struct.unpack(order + ("Q" if big else "I"), value)[0])
                value = f.read(struct.calcsize(code))
                f.seek(at)
            size[tag] = struct.unpack(order + code, value[:struct.calcsize(code)])[0]
    if 256 not in size or 257 not in size:
        return None
    return Claim(size[256], size[257], size.get(258, 8) > 8, bounded=False)


def _bmp(f: BinaryIO, head: bytes) -> Optional[Claim]:
    width, height = struct.unpack("<ii", head[18:26])
    return Claim(abs(width), abs(height), False)  # negative height: rows stored top down


def _exr(f: BinaryIO, head: bytes) -> Optional[Claim]:
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
            return Claim(x1 - x0 + 1, y1 - y0 + 1, True, bounded=False)
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


def _hdr(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """The resolution line after the header's blank line."""
    f.seek(0)
    for _ in range(_HDR_MAX_LINES):
        line = f.readline(_HDR_MAX_LINE)
        if not line:
            return None
        if not line.strip():
            match = _HDR_SIZE.match(f.readline(_HDR_MAX_LINE).strip())
            if match is None:
                return None
            first, n1, _, n2 = match.groups()
            rows, columns = (int(n1), int(n2)) if first == b"Y" else (int(n2), int(n1))
            return Claim(columns, rows, True)
    return None


def _webp(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """The canvas of a VP8X chunk, or the frame of a lossy (VP8) or lossless (VP8L) one."""
    if head[8:12] != b"WEBP":
        return None
    chunk = head[12:16]
    if chunk == b"VP8X":
        w, h = int.from_bytes(head[24:27], "little"), int.from_bytes(head[27:30], "little")
        return Claim(w + 1, h + 1, False, bounded=False)
    if chunk == b"VP8 ":
        w, h = struct.unpack("<HH", head[26:30])
        return Claim(w & 0x3FFF, h & 0x3FFF, False, bounded=False)
    if chunk == b"VP8L":
        bits, = struct.unpack("<I", head[21:25])
        return Claim((bits & 0x3FFF) + 1, ((bits >> 14) & 0x3FFF) + 1, False, bounded=False)
    return None


def _j2k(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """A JPEG 2000 codestream's SIZ segment: the image area, less its offset."""
    xsiz, ysiz, x0, y0 = struct.unpack(">IIII", head[8:24])
    return Claim(xsiz - x0, ysiz - y0, False, bounded=False)


def _jp2(f: BinaryIO, head: bytes) -> Optional[Claim]:
    """A JP2 file's image header box (ihdr: height, width), inside its jp2h box."""
    f.seek(0)
    data = f.read(1 << 16)
    at = data.find(b"ihdr")
    if at < 0:
        return None
    height, width = struct.unpack(">II", data[at + 4:at + 12])
    return Claim(width, height, False, bounded=False)


_SIGNATURES = [
    (b"\x89PNG\r\n\x1a\n", _png),
    (b"\xff\xd8", _jpeg),
    (b"II*\x00", _tiff),
    (b"MM\x00*", _tiff),
    (b"II+\x00", _tiff),  # BigTIFF
    (b"MM\x00+", _tiff),
    (b"BM", _bmp),
    (b"\x76\x2f\x31\x01", _exr),
    (b"#?", _hdr),  # Radiance: Blender asks for no more than this
    (b"\x01\xda", lambda f, h: Claim(*struct.unpack(">HH", h[6:10]), False)),          # Iris: xsize, ysize
    (b"DDS ", lambda f, h: Claim(*reversed(struct.unpack("<II", h[12:20])), False)),  # height, width
    (b"8BPS", lambda f, h: Claim(*reversed(struct.unpack(">II", h[14:22])), False)),  # PSD: height, width
    (b"RIFF", _webp),
    (b"SDPX", lambda f, h: Claim(*struct.unpack(">II", h[772:780]), True)),           # pixels, lines
    (b"XPDS", lambda f, h: Claim(*struct.unpack("<II", h[772:780]), True)),
    (b"\x80\x2a\x5f\xd7", lambda f, h: Claim(*struct.unpack(">II", h[200:208]), True)),  # Cineon
    (b"\xd7\x5f\x2a\x80", lambda f, h: Claim(*struct.unpack("<II", h[200:208]), True)),
    (b"\xff\x4f\xff\x51", _j2k),
    (b"\x00\x00\x00\x0cjP  \r\n\x87\n", _jp2),
]


def cut_short(f: BinaryIO) -> bool:
    """Whether f is a JPEG without an end-of-image marker after its first
    scan: a file cut short, which libjpeg decodes all the same, filling
    what is missing with grey. Scan data escapes its 0xFF bytes, so FF D9
    there is the end. The scan is found by walking the segments: an EXIF
    thumbnail's scan and end marker lie inside one of them."""
    f.seek(0)
    if f.read(2) != b"\xff\xd8":
        return False
    scan = next((f.tell() for marker in _jpeg_markers(f) if marker == 0xDA), None)
    if scan is None:
        return False
    f.seek(scan)
    return f.read().rfind(b"\xff\xd9") < 0


# bpy hands out an image's pixels as one array whose length is a C int, 4
# values per pixel: past it Blender 3.4 crashes and bpy 4.5 wraps the length.
MAX_PIXEL_VALUES = 2 ** 31 - 1
# Bytes per pixel while Blender decodes an image and the add-on reads it:
# Blender's buffer (4, or 16 for float images), the float copy bpy hands out
# (16) and the bytes made of it (4).
_READ_BYTES = {False: 24, True: 32}
# The formats that say Claim.bounded pack at most this many pixels into a
# byte of their file (deflate tops out near 1032 bytes a byte, JPEG's Huffman
# codes near 256 pixels a byte, run lengths far below): a header claiming
# more is forged, or its file cut short.
_MAX_PIXELS_PER_BYTE = 1 << 16


def size_problem(claim: Claim, file_bytes: Optional[int]) -> str:
    """Why an image claiming `claim`, from a file of file_bytes bytes (None:
    not from a file), cannot be decoded and read safely; "" when it can."""
    w, h, float_pixels = claim.width, claim.height, claim.float_pixels
    if 4 * w * h > MAX_PIXEL_VALUES:
        return (f"{w} x {h} pixels: more than Blender can hand to Python (4 values per pixel, at most "
                f"{MAX_PIXEL_VALUES:,} values, about 23,170 x 23,170 pixels)")
    if claim.bounded and file_bytes is not None and w * h > _MAX_PIXELS_PER_BYTE * file_bytes:
        return f"{w} x {h} pixels in {file_bytes:,} bytes, which cannot hold them (a file cut short or forged)"
    needed, memory = _READ_BYTES[float_pixels] * w * h, physical_memory()
    if memory is not None and needed > memory:
        return (f"{w} x {h} pixels: reading them takes about {needed / 2**30:.1f} GB, more than this machine's "
                f"{memory / 2**30:.0f} GB of memory")
    return ""


def physical_memory() -> Optional[int]:
    """This machine's memory in bytes; None where sysconf cannot tell (Windows)."""
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
