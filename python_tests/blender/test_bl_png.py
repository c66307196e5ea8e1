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
