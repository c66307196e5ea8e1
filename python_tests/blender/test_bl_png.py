# SPDX-License-Identifier: MIT
"""PNG files written by the add-on from baked pixels (png_files)."""

from __future__ import annotations

import io

import numpy as np
import pytest


def pixels(height=23, width=37, seed=1):
    return np.random.default_rng(seed).integers(0, 256, (height, width, 4), dtype=np.uint8)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_png_round_trips_through_pillow_top_row_first(pkg, channels):
    from PIL import Image

    image = pixels()[:, :, :channels]
    png = Image.open(io.BytesIO(pkg.png_files.encode_png(image)))
    assert png.mode == {1: "L", 3: "RGB", 4: "RGBA"}[channels]
    decoded = np.asarray(png).reshape(image.shape[:2] + (-1,))
    assert decoded.shape == image.shape
    assert np.array_equal(decoded, image[::-1])  # Blender's row 0 is the bottom one


def test_many_pngs_written_side_by_side_round_trip(pkg, tmp_path):
    """More images than threads, of every channel count and size, each in
    its own file: no image's stream lands in another's file."""
    from PIL import Image

    files = [(str(tmp_path / f"page{k}.png"), pixels(height=5 + 13 * k, width=3 + 7 * k, seed=k)[:, :, :channels])
             for k, channels in enumerate((1, 3, 4, 3, 1, 4, 3))]
    pkg.png_files.write_pngs(files)
    for path, image in files:
        decoded = np.asarray(Image.open(path)).reshape(image.shape[:2] + (-1,))
        assert np.array_equal(decoded, image[::-1]), path


def test_pixels_that_cannot_be_encoded_leave_every_file_as_it_was(pkg, tmp_path):
    earlier = [tmp_path / "page0.png", tmp_path / "page1.png"]
    for path in earlier:
        path.write_bytes(b"an earlier run's image")
    with pytest.raises(ValueError, match="uint8"):
        pkg.png_files.write_pngs([(str(earlier[0]), pixels()), (str(earlier[1]), pixels().astype(np.float32))])
    assert [path.read_bytes() for path in earlier] == [b"an earlier run's image"] * 2


def test_png_loads_into_blender_as_written(pkg, tmp_path):
    """RGBA, RGB and grey: Blender gives an RGB file opaque alpha and a grey
    one its grey in R, G and B."""
    import bpy

    files = [(str(tmp_path / f"page{k}.png"), pixels(seed=k)[:, :, :channels])
             for k, channels in enumerate((4, 4, 3, 1))]
    pkg.png_files.write_pngs(files)
    for path, written in files:
        img = bpy.data.images.load(path, check_existing=False)
        got = np.empty(len(img.pixels), np.float32)
        img.pixels.foreach_get(got)
        got = np.rint(got * 255).astype(np.uint8).reshape(written.shape[:2] + (4,))
        want = np.dstack([written[:, :, [0, 0, 0]] if written.shape[2] == 1 else written[:, :, :3],
                          written[:, :, 3] if written.shape[2] == 4 else np.full(written.shape[:2], 255, np.uint8)])
        assert np.array_equal(got, want), path
        assert img.depth == {1: 8, 3: 24, 4: 32}[written.shape[2]]
        bpy.data.images.remove(img)


@pytest.mark.parametrize("channels", [1, 3, 4])
def test_sixteen_bit_png_holds_its_samples(pkg, tmp_path, channels):
    """Big-endian samples, as Pillow (grey) and Blender (every layout, read raw) read them."""
    import bpy
    from PIL import Image

    image = np.random.default_rng(channels).integers(0, 65536, (23, 37, channels), dtype=np.uint16)
    if channels == 4:
        image[:, :, 3] = 65535  # Blender premultiplies a float buffer's colours by alpha
    path = tmp_path / "deep.png"
    path.write_bytes(pkg.png_files.encode_png(image))
    if channels == 1:
        assert np.array_equal(np.asarray(Image.open(path)).astype(np.uint16), image[::-1, :, 0])
    img = bpy.data.images.load(str(path), check_existing=False)
    img.colorspace_settings.name = "Non-Color"  # the samples as they are, not turned linear
    got = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(got)
    got = np.rint(got * 65535).reshape(image.shape[:2] + (4,))
    assert img.is_float and np.array_equal(got[:, :, :channels] if channels > 1 else got[:, :, :1], image)
    bpy.data.images.remove(img)


def test_png_refuses_other_pixel_formats(pkg):
    with pytest.raises(ValueError, match="uint8"):
        pkg.png_files.encode_png(np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        pkg.png_files.encode_png(np.zeros((4, 4, 4), np.float32))
    for empty in ((0, 4, 3), (4, 0, 3)):
        with pytest.raises(ValueError, match="no empty image"):
            pkg.png_files.encode_png(np.zeros(empty, np.uint8))


# --------------------------------------------------------------------------- reading
def _pillow_png(image, mode, **save) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).convert(mode).save(buf, "PNG", **save)
    return buf.getvalue()


@pytest.mark.parametrize("mode", ["RGB", "RGBA"])
def test_decode_png_reads_what_pillow_writes_with_adaptive_filters(pkg, native, mode):
    """Pillow picks a filter per row (Sub and Paeth on this image; the other
    types are tested on files written row type by row type, and natively)."""
    from PIL import Image

    smooth = np.cumsum(np.random.default_rng(2).integers(0, 9, (45, 61, 4)), axis=1).astype(np.uint8)
    data = _pillow_png(smooth, mode, optimize=True)
    expected = np.asarray(Image.open(io.BytesIO(data)))[::-1]
    assert pkg.png_files.plain_png_size(data[:pkg.png_files.HEADER_BYTES]) == (61, 45, len(mode))
    decoded = pkg.png_files.decode_png(data)
    assert decoded.shape == (45, 61, len(mode)) and np.array_equal(decoded, expected)


@pytest.mark.parametrize("mode", ["L", "LA", "P", "I;16"])
def test_png_formats_blender_converts_are_not_plain(pkg, native, mode):
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


def _with_chunk_changed(data: bytes, kind: bytes, change) -> bytes:
    """data with the first chunk of that kind replaced by change(its data), its CRC made right."""
    import struct
    import zlib

    pos = 8
    while data[pos + 4:pos + 8] != kind:
        pos += 12 + struct.unpack(">I", data[pos:pos + 4])[0]
    length = struct.unpack(">I", data[pos:pos + 4])[0]
    body = change(data[pos + 8:pos + 8 + length])
    chunk = struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    return data[:pos] + chunk + data[pos + 12 + length:]


def test_png_whose_header_or_crc_lies_is_refused(pkg, native):
    """A header claiming more pixels than the data could hold is refused
    before any buffer of that size is asked for; so is pixel data failing
    its CRC, as libpng (and Blender) refuse it."""
    import struct

    f = pkg.png_files
    data = f.encode_png(pixels())
    for width, height in ((2 ** 31 - 1, 2 ** 31 - 1), (2 ** 20, 2 ** 20)):
        huge = _with_chunk_changed(data, b"IHDR", lambda b: struct.pack(">II", width, height) + b[8:])
        assert f.plain_png_size(huge) == (width, height, 4)
        with pytest.raises(ValueError, match="more than its data holds"):
            f.decode_png(huge)
    too_wide = _with_chunk_changed(data, b"IHDR", lambda b: struct.pack(">I", 2 ** 31) + b[4:])
    assert f.plain_png_size(too_wide) is None
    bad = bytearray(data)
    bad[len(data) - 12 - 2] ^= 1  # a byte of the IDAT chunk's CRC (IEND follows it)
    with pytest.raises(ValueError, match="CRC"):
        f.decode_png(bytes(bad))
    assert f.ends_whole(data[-f.TAIL_BYTES:]) and not f.ends_whole(data[:-5][-f.TAIL_BYTES:])
