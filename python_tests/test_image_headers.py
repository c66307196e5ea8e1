# SPDX-License-Identifier: MIT
"""image_headers: the size an image file claims, read from its header alone,
so that the add-on can refuse an image before Blender decodes it."""

from __future__ import annotations

import io
import struct

import pytest
from PIL import Image

from atlas_defrag import image_headers
from atlas_defrag.image_headers import Claim


def _saved(fmt: str, size=(300, 200), **kw) -> bytes:
    out = io.BytesIO()
    Image.new("RGB", size, (90, 140, 30)).save(out, fmt, **kw)
    return out.getvalue()


def _claim(data: bytes, name: str = "") -> Claim:
    return image_headers.claimed_size(io.BytesIO(data), name)


@pytest.mark.parametrize("fmt, kw, name", [
    ("PNG", {}, "a.png"),
    ("JPEG", {}, "a.jpg"),
    # A progressive frame (SOF2) behind an EXIF segment and a comment.
    ("JPEG", {"progressive": True, "exif": b"Exif\x00\x00" + bytes(5000), "comment": b"scan"}, "a.jpg"),
    ("TIFF", {}, "a.tif"),
    ("BMP", {}, "a.bmp"),
    ("TGA", {}, "a.tga"),
    ("SGI", {}, "a.rgb"),
    ("DDS", {}, "a.dds"),
    ("WEBP", {}, "a.webp"),                   # lossy (VP8)
    ("WEBP", {"lossless": True}, "a.webp"),   # VP8L
    ("WEBP", {"exif": b"Exif\x00\x00" + bytes(20)}, "a.webp"),  # extended (VP8X)
    ("JPEG2000", {}, "a.jp2"),
    ("JPEG2000", {"no_jp2": True}, "a.j2k"),  # a bare codestream
])
def test_the_formats_blender_reads_claim_their_size(fmt, kw, name):
    assert _claim(_saved(fmt, **kw), name)[:3] == (300, 200, False)


def test_radiance_psd_dpx_and_cineon_headers_claim_their_size():
    """Formats Pillow does not write, their headers made by hand."""
    hdr = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 200 +X 300\n" + bytes(16)
    psd = b"8BPS" + struct.pack(">H6xHII", 1, 3, 200, 300) + bytes(16)
    dpx = b"SDPX" + bytes(768) + struct.pack(">II", 300, 200)
    dpx_little = b"XPDS" + bytes(768) + struct.pack("<II", 300, 200)
    cineon = b"\x80\x2a\x5f\xd7" + bytes(196) + struct.pack(">II", 300, 200)
    cineon_little = b"\xd7\x5f\x2a\x80" + bytes(196) + struct.pack("<II", 300, 200)
    assert _claim(hdr) == Claim(300, 200, True)
    assert _claim(hdr.replace(b"-Y 200 +X 300", b"+X 300 -Y 200")) == Claim(300, 200, True)
    assert _claim(hdr.replace(b"#?RADIANCE", b"#?")) == Claim(300, 200, True)  # all Blender asks for
    assert _claim(psd) == Claim(300, 200, False)
    for data in (dpx, dpx_little, cineon, cineon_little):  # Blender holds them as floats
        assert _claim(data) == Claim(300, 200, True), data[:4]


def test_a_tga_is_known_by_its_file_name_or_by_its_header_as_blender_knows_it():
    """A TGA has no signature: Blender goes by its colour-map type, image
    type and pixel depth, whatever the file is named."""
    assert _claim(_saved("TGA"), "texture.png")[:2] == (300, 200)
    assert _claim(b"\x00\x07" + bytes(30), "texture.png") is None  # image type 7: none


def test_sixteen_bit_files_are_held_as_floats():
    out = io.BytesIO()
    Image.new("I;16", (30, 20)).save(out, "PNG")
    assert _claim(out.getvalue()) == Claim(30, 20, True)
    out = io.BytesIO()
    Image.new("I;16", (30, 20)).save(out, "TIFF")
    assert _claim(out.getvalue())[:3] == (30, 20, True)


def _tiff(order: str, entries, big: bool = False) -> bytes:
    """A TIFF (or BigTIFF) holding only its first directory: (tag, type, value) entries."""
    word, value_size = ("Q", 8) if big else ("I", 4)
    ifd = struct.pack(order + ("Q" if big else "H"), len(entries))
    for tag, kind, value in entries:
        packed = struct.pack(order + ("H" if kind == 3 else "I"), value).ljust(value_size, b"\0")
        ifd += struct.pack(order + "HH" + word, tag, kind, 1) + packed
    if big:
        magic = (b"II+\x00" if order == "<" else b"MM\x00+") + struct.pack(order + "HH", 8, 0)
        return magic + struct.pack(order + "Q", 16) + ifd + bytes(8)
    magic = b"II*\x00" if order == "<" else b"MM\x00*"
    return magic + struct.pack(order + "I", 8) + ifd + b"\0\0\0\0"


@pytest.mark.parametrize("order", ["<", ">"])
@pytest.mark.parametrize("big", [False, True])
def test_tiff_sizes_are_read_in_either_byte_order_and_either_integer(order, big):
    data = _tiff(order, [(254, 4, 0), (256, 3, 40000), (257, 4, 70000)], big)
    assert _claim(data)[:3] == (40000, 70000, False)


def _exr(window) -> bytes:
    """An OpenEXR header: magic, version, then attributes (name, type, size, value)."""
    def attribute(name: bytes, kind: bytes, value: bytes) -> bytes:
        return name + b"\0" + kind + b"\0" + struct.pack("<i", len(value)) + value
    return (b"\x76\x2f\x31\x01" + struct.pack("<I", 2)
            + attribute(b"channels", b"chlist", bytes(37))
            + attribute(b"compression", b"compression", b"\x00")
            + attribute(b"dataWindow", b"box2i", struct.pack("<iiii", *window)) + b"\0")


def test_an_exr_claims_its_data_window_in_floats():
    assert _claim(_exr((-10, 5, 30009, 20004)))[:3] == (30020, 20000, True)


def test_a_jpeg_header_claiming_more_than_its_file_holds_is_read_as_claimed():
    data = bytearray(_saved("JPEG", size=(64, 64)))
    frame = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, frame + 5, 60000, 61000)  # height, width
    assert _claim(bytes(data)) == Claim(61000, 60000, False)


def _forged_jpeg(prefix: bytes) -> bytes:
    """A 64 x 64 JPEG claiming 60000 x 61000 pixels, `prefix` put before its frame header."""
    data = bytearray(_saved("JPEG", size=(64, 64)))
    frame = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, frame + 5, 60000, 61000)
    return bytes(data[:frame] + prefix + data[frame:])


@pytest.mark.parametrize("prefix", [
    b"\x00",                          # a junk byte, which libjpeg skips with a warning
    b"\xff\xfe\x00\x02" * 300,       # 300 empty comments
])
def test_a_jpeg_frame_header_is_found_wherever_libjpeg_finds_it(prefix):
    assert _claim(_forged_jpeg(prefix)) == Claim(61000, 60000, False)


def test_a_jpeg_of_more_segments_than_real_files_hold_claims_nothing():
    assert _claim(_forged_jpeg(b"\xff\xfe\x00\x02" * 70000)) is None


def test_a_jpeg_cut_short_is_told_from_a_whole_one():
    whole = _saved("JPEG", size=(64, 64))
    assert not image_headers.cut_short(io.BytesIO(whole))
    assert image_headers.cut_short(io.BytesIO(whole[:-10]))  # cut inside its scan data
    assert not image_headers.cut_short(io.BytesIO(_saved("PNG")[:40]))  # not a JPEG: not judged here
    # An EXIF thumbnail (a whole JPEG inside an APP1 segment) does not hide the cut.
    thumbnail = b"Exif\x00\x00\xff\xd8\xff\xda\x00\x02\x00\xff\xd9"
    app1 = b"\xff\xe1" + struct.pack(">H", len(thumbnail) + 2) + thumbnail
    assert image_headers.cut_short(io.BytesIO(whole[:2] + app1 + whole[2:-10]))
    assert not image_headers.cut_short(io.BytesIO(whole[:2] + app1 + whole[2:]))


def test_a_jpeg_cut_anywhere_in_its_header_is_read_without_an_error():
    """Cut one byte into a segment's length, say: the walk over the segments
    ends there, as the file does (Blender then cannot decode it, and says so)."""
    whole = _saved("JPEG", size=(64, 64))
    for end in range(2, whole.find(b"\xff\xda") + 8):
        image_headers.cut_short(io.BytesIO(whole[:end]))
        image_headers.claimed_size(io.BytesIO(whole[:end]), "t.jpg")


def test_formats_that_pack_flat_images_tightly_are_not_taken_for_forged():
    """A flat lossless WebP is a few dozen bytes at any size (as a black
    metallic map may be); a JPEG of that size cannot be."""
    out = io.BytesIO()
    Image.new("RGB", (2048, 2048), (0, 0, 0)).save(out, "WEBP", lossless=True, method=0)
    assert len(out.getvalue()) < 100
    assert image_headers.size_problem(_claim(out.getvalue()), len(out.getvalue())) == ""
    forged = _claim(_forged_jpeg(b""))
    assert "cannot hold them" in image_headers.size_problem(forged._replace(width=2048, height=2048), 50)


@pytest.mark.parametrize("claim, file_bytes, problem", [
    (Claim(4096, 4096, False), 2_000_000, ""),
    (Claim(4096, 4096, False), None, ""),                     # pixels Blender holds: no file to judge
    (Claim(16000, 16000, False), 3_000, "cannot hold them"),  # 85,000 pixels a byte
    (Claim(23171, 23171, False), 10 ** 9, "more than Blender can hand to Python"),
])
def test_size_problems(claim, file_bytes, problem):
    found = image_headers.size_problem(claim, file_bytes)
    assert (problem in found) if problem else found == ""


def test_a_claim_beyond_memory_is_a_problem(monkeypatch):
    monkeypatch.setattr(image_headers, "physical_memory", lambda: 8 * 2 ** 30)
    assert "more than this machine's 8 GB" in image_headers.size_problem(Claim(20000, 20000, False), 10 ** 9)
    assert image_headers.size_problem(Claim(16000, 16000, False), 10 ** 9) == ""


@pytest.mark.parametrize("data", [
    b"",
    b"\x89PNG\r\n\x1a\n\x00\x00",       # cut inside its header
    b"\xff\xd8\xff\xe0\x00\x10JFIF",     # cut before its frame header
    b"\xff\xd8" + b"\xff" * 100,         # fill bytes to the end
    b"\xff\xd8\xff\xda\x00\x08" + bytes(8),  # scan data before any frame header
    b"II*\x00\xff\xff\xff\x7f",          # a directory off the file
    b"\x76\x2f\x31\x01" + bytes(4) + b"\0",  # an EXR without a data window
    b"GIF89a" + bytes(20),               # a format not read here
])
def test_headers_that_are_cut_short_malformed_or_unknown_claim_nothing(data):
    assert _claim(data, "texture") is None


@pytest.mark.parametrize("name", ["meshroom", "tetra"])
def test_the_shared_scans_textures_claim_what_pillow_decodes(scan_path, name):
    files = [p for p in scan_path(name).parent.rglob("*") if p.suffix.lower() in (".png", ".jpg", ".jpeg")]
    assert files
    for path in files:
        with open(path, "rb") as f, Image.open(path) as im:
            assert image_headers.claimed_size(f, path.name)[:2] == im.size, path
