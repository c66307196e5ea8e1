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
