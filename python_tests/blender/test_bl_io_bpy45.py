# SPDX-License-Identifier: MIT
"""The bpy read/write layers in the bpy 4.5 module, without the native core:
reading real scans, writing a given layout, error cases, rollback."""

from __future__ import annotations

import os

import bpy
import numpy as np
import pytest

import blhelp as H
import bl_scenarios as S


identity_result = S.identity_result


def test_read_tetra(pkg):
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    before = H.object_state(obj.name)
    r = pkg.read_bpy.read(obj)
    m = r.job.mesh
    assert m.triangles.shape == (13666, 3) and m.uvs.shape == (13666, 3, 2)
    assert m.positions.dtype == np.float64 and m.triangles.dtype == np.int32
    assert m.triangles.max() < len(m.positions)
    assert set(np.unique(m.face_page)) == {0}
    assert [(im.role, im.image) for im in r.job.pages[0].maps] == [("base_color", "textured_0_v2.jpg")]
    img = r.job.images["textured_0_v2.jpg"]
    # This JPEG holds RGB: Blender's opaque alpha is not kept.
    assert img.pixels.shape == (2048, 2048, 3) and img.pixels.dtype == np.uint8
    assert img.colorspace == "sRGB" and not img.is_float
    # Row 0 is the bottom row, as Blender stores it.
    flat = np.empty(2048 * 2048 * 4, np.float32)
    bpy.data.images["textured_0_v2.jpg"].pixels.foreach_get(flat)
    assert np.array_equal(img.pixels[0, :16], np.rint(flat[:64] * 255).reshape(16, 4)[:, :3])
    # The missing normal-map image is skipped with a warning.
    assert any("no pixels" in w for w in r.warnings), r.warnings
    # UVs per corner equal the loop UVs.
    me = obj.data
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers.active.data.foreach_get("uv", uv)
    assert np.allclose(m.uvs, uv.reshape(-1, 2)[r.tri_loops])
    assert H.object_state(obj.name) == before


def test_byte_pixels_read_back_exactly(pkg, tmp_path):
    """Every byte value of a byte image comes back as itself from bpy's floats."""
    import bpy

    codes = np.arange(256 * 4, dtype=np.uint8).reshape(16, 16, 4)
    img = bpy.data.images.new("all_codes", 16, 16, alpha=True)
    img.pixels.foreach_set((codes.astype(np.float32) / 255).ravel())
    path = str(tmp_path / "all_codes.png")
    img.filepath_raw, img.file_format = path, "PNG"
    img.save()
    loaded = bpy.data.images.load(path)
    try:
        assert not loaded.is_float
        assert np.array_equal(pkg.read_bpy.read_pixels(loaded), codes)
    finally:
        bpy.data.images.remove(loaded)
        bpy.data.images.remove(img)


def test_read_gltf_roles(pkg):
    H.reset()
    obj = H.import_model(H.model_path("smithsonian"))
    r = pkg.read_bpy.read(obj)
    page = r.job.pages[0]
    roles = {m.role: m for m in page.maps}
    assert set(roles) == {"base_color", "normal", "occlusion"}, roles
    assert roles["normal"].normal_map and not roles["base_color"].normal_map
    assert r.job.images[roles["normal"].image].colorspace == "Non-Color"
    assert r.job.mesh.triangles.shape == (100000, 3)


def test_read_multi_material(pkg):
    """Several materials with different images: one page each, one group."""
    H.reset()
    objs = []
    for i in range(2):
        objs.append(H.textured_plane(name=f"P{i}", image_size=(32 * (i + 1), 32)))
    H.make_active(objs[0])
    for o in objs:
        o.select_set(True)
    bpy.ops.object.join()
    obj = bpy.context.active_object
    r = pkg.read_bpy.read(obj)
    assert len(r.job.pages) == 2
    assert {p.group for p in r.job.pages} == {0}
    assert sorted(np.unique(r.job.mesh.face_page).tolist()) == [0, 1]
    assert pkg.job.page_sizes_of(r.job).tolist() == [[32, 32], [64, 32]]


def test_write_identity_layout(pkg):
    S.write_identity_layout(pkg)


def test_material_index_past_the_slots_keeps_drawing_with_the_last(pkg):
    S.material_index_past_the_slots_keeps_drawing_with_the_last(pkg)


def test_write_rolls_back_on_failure(pkg, monkeypatch):
    obj, name, before, settings, read = S.prepared(pkg, "smithsonian")
    result = identity_result(pkg, read)
    calls = []
    real = pkg.write_bpy._rewire_material

    def failing(*a, **k):
        real(*a, **k)
        calls.append(1)
        raise RuntimeError("injected failure")
    monkeypatch.setattr(pkg.write_bpy, "_rewire_material", failing)
    with pytest.raises(RuntimeError, match="injected"):
        pkg.api.finish(obj, read, result, settings)
    assert calls
    after = H.object_state(name)
    assert after == before, S._diff(before, after)


def test_write_refuses_changed_mesh(pkg):
    H.reset()
    obj = H.textured_plane()
    settings = pkg.api.Settings.from_kwargs()
    read = pkg.api.prepare(obj, settings)
    result = identity_result(pkg, read)
    obj.data.uv_layers.new(name="Other")
    before = H.object_state(obj.name)
    with pytest.raises(pkg.DefragError, match="changed"):
        pkg.api.finish(obj, read, result, settings)
    assert H.object_state(obj.name) == before


def test_write_float_image_and_save(pkg, tmp_path):
    """Float images stay float (EXR); storage='SAVE' writes files in image_dir."""
    H.reset()
    obj = H.textured_plane(float_buffer=True, image_size=(16, 8))
    settings = pkg.api.Settings.from_kwargs(storage="SAVE", image_dir=str(tmp_path))
    read = pkg.api.prepare(obj, settings)
    src = next(iter(read.job.images.values()))
    assert src.pixels.dtype == np.float32 and src.is_float
    result = identity_result(pkg, read)
    report = pkg.api.finish(obj, read, result, settings)
    img = bpy.data.images[report["images"][0]]
    assert img.is_float and img.source == "FILE"
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["Plane_tex_defrag.exr"], files
    b = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(b)
    assert np.allclose(b.reshape(8, 16, 4), src.pixels, atol=1e-4)


def _png16_samples(path) -> np.ndarray:
    """(H, W, C) uint16 samples, row 0 at the bottom, of a 16-bit PNG as png_files writes it (Up filters)."""
    import struct
    import zlib

    data = open(path, "rb").read()
    width, height, depth, colour = struct.unpack(">IIBB", data[16:26])
    assert depth == 16, depth
    channels = {0: 1, 2: 3, 6: 4}[colour]
    rows = np.frombuffer(zlib.decompress(data[41:data.index(b"IEND") - 8]), np.uint8).reshape(height, -1)
    assert set(rows[:, 0]) <= {2}, set(rows[:, 0])
    raw = np.cumsum(rows[:, 1:], axis=0, dtype=np.uint8)  # undoes Up, modulo 256
    return raw.view(">u2").reshape(height, width, channels)[::-1].astype(np.uint16)


@pytest.mark.parametrize("alpha_mode", ["STRAIGHT", "CHANNEL_PACKED", "PREMUL"])
def test_sixteen_bit_colour_map_stays_a_sixteen_bit_png(pkg, tmp_path, alpha_mode):
    """A 16-bit sRGB map (Blender holds it as linear floats, premultiplied) is
    written as a 16-bit PNG of the same samples, straight alpha kept: as
    OpenEXR it held sRGB values, which other readers take for linear (an OBJ
    reopened twice as bright), and half-transparent texels took colours
    premultiplied twice. Under other alpha modes it stays OpenEXR, which
    Blender reads back as it was."""
    H.reset()
    rng = np.random.default_rng(5)
    source = rng.integers(0, 65536, (8, 16, 4), dtype=np.uint16)
    source[:, :8, 3] = 65535
    source[:, 8:, 3] = 20000  # about 0.3
    (tmp_path / "in").mkdir()
    path = tmp_path / "in" / "deep.png"
    path.write_bytes(pkg.png_files.encode_png(source))
    obj = H.textured_plane(image_size=(16, 8))
    node = next(n for n in H.image_nodes(obj.material_slots[0].material))
    node.image = bpy.data.images.load(str(path))
    node.image.alpha_mode = alpha_mode
    assert node.image.is_float and node.image.colorspace_settings.name == "sRGB"
    settings = pkg.api.Settings.from_kwargs(storage="SAVE", image_dir=str(tmp_path / "out"))
    read = pkg.api.prepare(obj, settings)
    report = pkg.api.finish(obj, read, identity_result(pkg, read), settings)
    img = bpy.data.images[report["images"][0]]
    if alpha_mode != "STRAIGHT":
        assert img.filepath.endswith(".exr"), img.filepath
        got, want = np.empty(len(img.pixels), np.float32), np.empty(len(node.image.pixels), np.float32)
        img.pixels.foreach_get(got)
        node.image.pixels.foreach_get(want)
        assert np.allclose(got, want, atol=1e-4), np.abs(got - want).max()
        return
    assert img.is_float and img.colorspace_settings.name == "sRGB" and img.filepath.endswith(".png"), img.filepath
    written = _png16_samples(bpy.path.abspath(img.filepath))
    assert np.array_equal(written[:, :, 3], source[:, :, 3])
    error = np.abs(written[:, :, :3].astype(np.int64) - source[:, :, :3])
    assert error[:, :8].max() <= 2 and error[:, 8:].max() <= 8, (error[:, :8].max(), error[:, 8:].max())


def test_packed_images_unpack_beside_the_blend(pkg, tmp_path):
    """Unpacked to their original place, the new images land beside the
    .blend, not in the temporary folder they were written to first (which
    Blender deletes on exit)."""
    H.reset()
    obj = H.textured_plane(image_size=(16, 8))
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    report = pkg.defragment(bpy.data.objects[obj.name])
    img = bpy.data.images[report["images"][0]]
    pixels = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(pixels)
    assert img.packed_file is not None and img.filepath == "//Plane_tex_defrag.png", img.filepath
    img.unpack(method="WRITE_ORIGINAL")
    assert (tmp_path / "Plane_tex_defrag.png").is_file(), sorted(p.name for p in tmp_path.iterdir())
    again = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(again)
    assert np.array_equal(again, pixels)


def test_packed_images_take_a_name_beside_the_blend_no_other_has(pkg, tmp_path):
    """Two runs whose new images would share a file name, and a file of that
    name already beside the .blend: each packed image names a file of its own."""
    H.reset()
    a, b = H.textured_plane("A"), H.textured_plane("B")
    bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    (tmp_path / "A_tex_defrag.png").write_bytes(b"the user's own file")
    first = pkg.defragment(bpy.data.objects["A"])["images"][0]
    bpy.data.images["A_tex"].name = "A_tex_before"
    bpy.data.images["B_tex"].name = "A_tex"  # B's new image is named as A's was
    second = pkg.defragment(bpy.data.objects["B"])["images"][0]
    paths = [bpy.data.images[n].filepath for n in (first, second)]
    assert paths == ["//A_tex_defrag.001.png", "//A_tex_defrag.002.png"], paths
    assert (tmp_path / "A_tex_defrag.png").read_bytes() == b"the user's own file"


def test_settings_validation(pkg):
    with pytest.raises(pkg.DefragError, match="weighting"):
        pkg.api.Settings.from_kwargs(weighting="xyz")
    with pytest.raises(pkg.DefragError, match="padding"):
        pkg.api.Settings.from_kwargs(padding=-1)
    with pytest.raises(pkg.DefragError, match="unknown"):  # not a raw TypeError (issue 15)
        pkg.api.Settings.from_kwargs(bogus=1)


@pytest.mark.parametrize("case", sorted(S.ERRORS))
def test_error_cases(pkg, case):
    msg = S.error_case(pkg, case)
    assert msg


def test_operator_registered_in_menus(pkg):
    assert hasattr(bpy.types, "UV_OT_defragment_atlas")
    op = bpy.ops.uv.defragment_atlas
    assert op.get_rna_type().name == "Defragment Texture Atlas"
    for menu in ("IMAGE_MT_uvs", "VIEW3D_MT_uv_map"):
        funcs = getattr(bpy.types, menu)._dyn_ui_initialize()
        assert pkg.operators.menu_func in funcs, menu


def test_operator_properties_follow_the_schema(pkg):
    props = bpy.ops.uv.defragment_atlas.get_rna_type().properties
    for o in pkg.options.SCHEMA:
        p = props[o.name]
        assert p.name == o.label and p.description == o.help, o.name
        if o.choices:
            assert [i.identifier for i in p.enum_items] == [c.value.upper() for c in o.choices]
            assert p.default == o.default.upper()
            continue
        if o.kind is bool:
            assert p.type == "BOOLEAN" and p.default is o.default, o.name
            continue
        # Soft bounds: the options' check refuses what is out of range in words.
        assert p.soft_min == pytest.approx(o.low, rel=1e-6), o.name
        if o.high is not None:
            assert p.soft_max == pytest.approx(o.high, rel=1e-6), o.name
        if o.automatic:
            assert props["automatic_" + o.name].default is True
            assert p.default == o.manual_default
        else:
            assert p.default == pytest.approx(o.default)


def test_import_textured_scan_ply(pkg, tmp_path):
    """File > Import > Textured Scan PLY: the per-face UVs and the TextureFile
    image reach the mesh, which the add-on then reads as the OBJ's; a broken
    file is reported and adds nothing."""
    H.reset()
    textured = H.openmvs_style_ply(tmp_path / "scan.ply")
    assert bpy.ops.import_mesh.textured_scan_ply(filepath=str(tmp_path / "scan.ply")) == {"FINISHED"}
    obj = bpy.context.view_layer.objects.active
    assert obj.name == "scan" and len(obj.data.polygons) == 13666 and obj.data.uv_layers.active.name == "UVMap"
    r = pkg.read_bpy.read(obj)
    assert [m.image for m in r.job.pages[0].maps] == ["textured_0_v2.jpg"]
    assert int((r.job.mesh.face_page >= 0).sum()) == textured
    data = (tmp_path / "scan.ply").read_bytes()
    (tmp_path / "gone.ply").write_bytes(data.replace(b"comment TextureFile ", b"comment TextureFile gone/"))
    assert bpy.ops.import_mesh.textured_scan_ply(filepath=str(tmp_path / "gone.ply")) == {"FINISHED"}
    gone = bpy.context.view_layer.objects.active
    assert gone.name == "gone" and not gone.data.materials and gone.data.uv_layers
    (tmp_path / "cut.ply").write_bytes(data[:-100])
    count = len(bpy.data.objects)
    with pytest.raises(RuntimeError, match="ends inside its 'face' element"):
        bpy.ops.import_mesh.textured_scan_ply(filepath=str(tmp_path / "cut.ply"))
    assert len(bpy.data.objects) == count


def test_import_ply_drops_faces_blender_cannot_hold(pkg, tmp_path):
    """A face naming a vertex twice and a repeated face go, as Blender's own importers drop them."""
    H.reset()
    path = tmp_path / "bad faces.ply"
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                    "property float z\nproperty float s\nproperty float t\nelement face 4\n"
                    "property list uchar int vertex_indices\nend_header\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n"
                    "0 1 0 0 1\n3 0 1 2\n3 0 2 3\n3 0 0 1\n3 0 1 2\n")
    assert bpy.ops.import_mesh.textured_scan_ply(filepath=str(path)) == {"FINISHED"}
    me = bpy.context.view_layer.objects.active.data
    assert len(me.polygons) == 2 and len(me.uv_layers[0].data) == 6


def test_import_ply_shades_with_its_vertex_normals(pkg, tmp_path):
    """nx ny nz become the mesh's custom normals, smooth shaded, as the file
    shades it."""
    H.reset()
    head = ("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\nelement face 2\n"
            "property list uchar int vertex_indices\nend_header\n")
    normals = np.array([[0, 0, 1], [0.6, 0, 0.8], [0, 0.6, 0.8], [0, 0, 1]])
    rows = "".join(f"{x} {y} 0 {n[0]} {n[1]} {n[2]}\n" for (x, y), n in zip([(0, 0), (1, 0), (1, 1), (0, 1)], normals))
    (tmp_path / "shaded.ply").write_text(head + rows + "3 0 1 2\n3 0 2 3\n")
    assert bpy.ops.import_mesh.textured_scan_ply(filepath=str(tmp_path / "shaded.ply")) == {"FINISHED"}
    me = bpy.context.view_layer.objects.active.data
    corner = np.array([n.vector[:] for n in me.corner_normals])
    vertex = np.array([lp.vertex_index for lp in me.loops])
    assert all(p.use_smooth for p in me.polygons) and np.allclose(corner, normals[vertex], atol=1e-4)


def test_read_gltf_wrap_emulation_and_transforms(pkg):
    """glTF mirrored-repeat emulation (maths between UV map and image) is a
    plain UV lookup; a texture transform (Mapping) is not, and says so."""
    H.reset()
    obj = H.import_model(str(H.ASSIMP / "glTF2" / "BoxTextured-glTF" / "BoxTextured.gltf"))
    r = pkg.read_bpy.read(obj)
    assert [m.image for m in r.job.pages[0].maps] == ["CesiumLogoFlat.png"]
    H.reset()
    obj = H.import_model(str(H.ASSIMP / "glTF2" / "textureTransform" / "TextureTransformTest.gltf"))
    before = H.object_state(obj.name)
    with pytest.raises(pkg.DefragError, match="coordinate transform"):
        pkg.read_bpy.read(obj)
    assert H.object_state(obj.name) == before


def test_write_float_image_packed(pkg):
    """Packed float images: written to a temporary EXR first, then packed; the
    path ends in the image's name (what exporters name the texture), and the
    temporary file is gone once the bytes are packed."""
    H.reset()
    obj = H.textured_plane(float_buffer=True, image_size=(16, 8))
    settings = pkg.api.Settings.from_kwargs()
    read = pkg.api.prepare(obj, settings)
    src = next(iter(read.job.images.values()))
    report = pkg.api.finish(obj, read, identity_result(pkg, read), settings)
    img = bpy.data.images[report["images"][0]]
    assert img.is_float and img.packed_file is not None
    assert img.filepath == "//Plane_tex_defrag.exr", img.filepath  # not the temporary file, gone
    b = np.empty(len(img.pixels), np.float32)
    img.pixels.foreach_get(b)
    assert np.allclose(b.reshape(8, 16, 4), src.pixels, atol=1e-4)
