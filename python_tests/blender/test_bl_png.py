# SPDX-License-Identifier: MIT
"""PNG files written by the add-on from baked pixels (png_files)."""

from __future__ import annotations

import io

import numpy as np
import pytest


def pixels(height=23, width=37, seed=1):
    return np.random.default_rng(seed).integers(0, 256, (height, width, 4), dtype=np.uint8)


@pytest.mark.parametrize("channels", [3, 4])
def test_png_round_trips_through_pillow_top_row_first(pkg, channels):
    from PIL import Image

    image = pixels()[:, :, :channels]
    decoded = np.asarray(Image.open(io.BytesIO(pkg.png_files.encode_png(image))))
    assert decoded.shape == image.shape
    assert np.array_equal(decoded, image[::-1])  # Blender's row 0 is the bottom one


@pytest.mark.parametrize("part_bytes", [1, 150, 10 ** 9])
def test_png_in_parts_round_trips(pkg, tmp_path, monkeypatch, part_bytes):
    """Parts (one row, a few rows, the whole image) compressed apart make one
    valid stream, through encode_png and write_pngs alike."""
    from PIL import Image

    monkeypatch.setattr(pkg.png_files, "_PART_BYTES", part_bytes)
    image = pixels(height=41)
    decoded = np.asarray(Image.open(io.BytesIO(pkg.png_files.encode_png(image))))
    assert np.array_equal(decoded, image[::-1])
    path = str(tmp_path / "parts.png")
    pkg.png_files.write_pngs([(path, image)])
    assert np.array_equal(np.asarray(Image.open(path)), image[::-1])


def test_adler32_of_parts_combines_as_zlib_computes_it(pkg):
    import zlib

    data = np.random.default_rng(3).integers(0, 256, 300000, dtype=np.uint8).tobytes()
    for cut in (0, 1, 65521, 123457, len(data)):
        a, b = data[:cut], data[cut:]
        assert pkg.png_files._adler32_combine(zlib.adler32(a), zlib.adler32(b), len(b)) == zlib.adler32(data)


def test_png_loads_into_blender_as_written(pkg, tmp_path):
    import bpy

    files = [(str(tmp_path / f"page{k}.png"), pixels(seed=k)) for k in range(3)]
    pkg.png_files.write_pngs(files)
    for path, rgba in files:
        img = bpy.data.images.load(path, check_existing=False)
        got = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(got)
        assert np.array_equal(np.rint(got * 255).astype(np.uint8).reshape(rgba.shape), rgba), path
        bpy.data.images.remove(img)


def test_png_refuses_other_pixel_formats(pkg):
    with pytest.raises(ValueError, match="uint8"):
        pkg.png_files.encode_png(np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        pkg.png_files.encode_png(np.zeros((4, 4, 4), np.float32))


# --------------------------------------------------------------------------- reading
def _pillow_png(image, mode, **save) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).convert(mode).save(buf, "PNG", **save)
    return buf.getvalue()


@pytest.mark.parametrize("mode", ["RGB", "RGBA"])
def test_decode_png_reads_what_pillow_writes_with_adaptive_filters(pkg, native, mode):
    """optimize=True makes Pillow pick a filter per row (Paeth among them)."""
    from PIL import Image

    smooth = np.cumsum(np.random.default_rng(2).integers(0, 9, (45, 61, 4)), axis=1).astype(np.uint8)
    data = _pillow_png(smooth, mode, optimize=True)
    expected = np.asarray(Image.open(io.BytesIO(data)).convert("RGBA"))[::-1]
    assert pkg.png_files.plain_png_size(data[:pkg.png_files.HEADER_BYTES]) == (61, 45, len(mode))
    decoded = pkg.png_files.decode_png(data)
    assert decoded.shape == (45, 61, 4) and np.array_equal(decoded, expected)


@pytest.mark.parametrize("mode", ["L", "LA", "P", "I;16"])
def test_png_formats_blender_converts_are_not_plain(pkg, mode):
    data = _pillow_png(pixels(), mode)
    assert pkg.png_files.plain_png_size(data[:pkg.png_files.HEADER_BYTES]) is None
    with pytest.raises(ValueError, match="8-bit"):
        pkg.png_files.decode_png(data)


def test_interlaced_or_damaged_png_is_refused(pkg, native):
    import struct
    import zlib

    f = pkg.png_files
    data = f.encode_png(pixels())
    interlaced = bytearray(data)
    interlaced[28] = 1  # IHDR's interlace method, its CRC made right again
    interlaced[29:33] = struct.pack(">I", zlib.crc32(bytes(interlaced[12:29])) & 0xFFFFFFFF)
    assert f.plain_png_size(bytes(interlaced)) is None
    bad_crc = bytearray(data)
    bad_crc[32] ^= 1
    assert f.plain_png_size(bytes(bad_crc)) is None
    with pytest.raises(ValueError):
        f.decode_png(data[:len(data) // 2])  # cut before IEND
    broken = bytearray(data)
    broken[60] ^= 0xFF  # a byte inside the zlib stream
    with pytest.raises(ValueError):
        f.decode_png(bytes(broken))
