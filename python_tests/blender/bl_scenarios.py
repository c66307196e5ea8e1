# SPDX-License-Identifier: MIT
"""Test scenarios run identically in Blender 3.4 (bl_runner.py, subprocess)
and in the bpy 4.5 module (pytest, in process). Each takes the add-on package
and raises AssertionError on failure; some return observations."""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import tempfile
import threading

import bpy
import numpy as np

import blhelp as H

# --------------------------------------------------------------------------- checks


def check_result(obj_name, before, report, *, duplicate=False):
    """The operator's promises, given the state before it ran."""
    obj = bpy.data.objects[obj_name]
    me = obj.data
    src_uv = before["uv_active"]
    new_uv = report["uv_map"] if report else src_uv + "_defrag"
    assert new_uv == src_uv + "_defrag", (new_uv, src_uv)
    old = before["uv_maps"]
    first = report.get("new_map_first", True) if report else True
    expected = [new_uv] + old[1:] + old[:1] if first else old + [new_uv]
    assert [u.name for u in me.uv_layers] == expected, ([u.name for u in me.uv_layers], expected)
    assert me.uv_layers.active.name == new_uv
    assert me.uv_layers[new_uv].active_render
    # The old UV map and old images are byte-for-byte unchanged.
    assert H.uv_hash(me, src_uv) == before["uv_hash"][src_uv]
    for name, st in before["image_state"].items():
        assert name in bpy.data.images, f"image {name} removed"
        assert H.image_state(bpy.data.images[name]) == st, f"image {name} changed"
    # Geometry unchanged.
    after = H.object_state(obj_name, pixels=False)
    for key in ("vertices.co", "loops.vertex_index"):
        assert after[key] == before[key], key
    # The new UV map differs from the old one and lies in [0, 1] for textured faces.
    assert H.uv_hash(me, new_uv) != before["uv_hash"][src_uv], "the new UV map equals the old one"
    # New images: <image>_defrag, non-blank, same colour space and buffer type.
    new_images = [i for i in bpy.data.images if i.name not in before["images"]]
    assert new_images, "no new image"
    for img in new_images:
        m = re.match(r"(.+)_defrag(_\d+)?(\.\d{3})?$", img.name)
        assert m, img.name
        src = next(bpy.data.images[n] for n in before["images"] if _stem(n) == m.group(1))
        assert img.colorspace_settings.name == src.colorspace_settings.name, img.name
        assert bool(img.is_float) == bool(src.is_float), img.name
        assert img.source == "FILE" and (img.packed_file is not None or os.path.isfile(
            bpy.path.abspath(img.filepath))), (img.name, img.source, img.filepath)
        assert img.size[0] > 0 and img.size[1] > 0
        assert H.image_variance(img) > 0.01, f"{img.name} is blank"
    # Materials point to the new images through a UV Map node naming the new map.
    rewired = 0
    for slot in obj.material_slots:
        mat = slot.material
        if mat is None or mat.node_tree is None:
            continue
        for node in H.image_nodes(mat):
            if node.image is not None and node.image in new_images:
                assert H.vector_uv_map(node) == new_uv, (mat.name, node.name, H.vector_uv_map(node))
                rewired += 1
    assert rewired, "no material uses the new images"
    if duplicate:
        for name, st in before["materials"].items():
            assert H.tree_state(bpy.data.materials[name]) == st, f"original material {name} changed"
        rewired_slots = [s.material.name for s in obj.material_slots
                         if s.material and s.material.name not in before["materials"]]
        assert rewired_slots and all(m in report["materials"] for m in rewired_slots), rewired_slots
    return new_images


@contextlib.contextmanager
def scratch_folder(prefix):
    """A temporary folder, removed afterwards with what the scenario wrote there."""
    folder = tempfile.mkdtemp(prefix=prefix)
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _stem(image_name):
    """'photo.jpg' -> 'photo', as the new images are named."""
    return re.sub(r"\.(png|jpe?g|tga|tiff?|exr|bmp|webp)$", "", image_name, flags=re.IGNORECASE)


class _raises:
    """pytest.raises inside Blender: exc (with `match` in its message) must be raised."""

    def __init__(self, exc, match: str = ""):
        self.exc, self.match = exc, match

    def __enter__(self):
        return self

    def __exit__(self, typ, value, tb):
        if typ is None:
            raise AssertionError(f"{self.exc.__name__} not raised")
        return issubclass(typ, self.exc) and self.match in str(value)


def run_operator(pkg, undo=False, **props):
    """Runs the operator; undo=True pushes its undo step as the UI does."""
    if undo:
        return bpy.ops.uv.defragment_atlas("EXEC_DEFAULT", True, **props)
    return bpy.ops.uv.defragment_atlas("EXEC_DEFAULT", **props)


# --------------------------------------------------------------------------- scenarios


def operator_on_model(pkg, model="tetra", **props):
    """Operator on a model: new map + images + rewired materials, old data
    unchanged; one undo restores everything exactly."""
    H.reset()
    obj = H.import_model(H.model_path(model))
    name = obj.name
    before = H.object_state(name)
    H.undo_push("before defragment")
    result = run_operator(pkg, undo=True, **props)
    assert result == {"FINISHED"}, result
    check_result(name, before, None)
    H.undo()
    after_undo = H.object_state(name)
    assert after_undo == before, _diff(before, after_undo)
    return {"faces": len(bpy.data.objects[name].data.polygons)}


def edit_mode_undo(pkg):
    """From Edit mode: returns to Edit mode; one undo restores the object."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    name = obj.name
    bpy.ops.object.mode_set(mode="EDIT")
    before = H.object_state(name)
    H.undo_push("before defragment")
    assert run_operator(pkg, undo=True) == {"FINISHED"}
    obj = bpy.data.objects[name]
    assert obj.mode == "EDIT", obj.mode
    bpy.ops.object.mode_set(mode="OBJECT")
    check_result(name, dict(before), None)
    bpy.ops.object.mode_set(mode="EDIT")
    H.undo()
    after = H.object_state(name)
    assert after == before, _diff(before, after)


def python_entry(pkg):
    """atlas_defrag.defragment(obj, **options) returns the report."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    before = H.object_state(obj.name)
    report = pkg.defragment(obj, target_charts=0, weighting="3d", padding=2)
    for key in ("charts_before", "charts_after", "seam_before", "seam_after", "seconds", "uv_map",
                "images", "materials", "warnings"):
        assert key in report, key
    assert report["charts_after"] < report["charts_before"], report
    assert report["seconds"]["total"] > 0
    check_result(obj.name, before, report)
    import json
    json.dumps(report)  # plain data
    return {k: report[k] for k in ("charts_before", "charts_after", "seam_before", "seam_after")}


def duplicate_materials_and_removal(pkg):
    """With duplicate materials the originals are untouched, and removing what
    the operator added restores the original object exactly."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    name = obj.name
    before = H.object_state(name)
    report = pkg.defragment(obj, duplicate_materials=True)
    check_result(name, before, report, duplicate=True)
    assert report["materials"], report
    obj = bpy.data.objects[name]
    # Remove what was added.
    me = obj.data
    for s, (orig, _) in zip(obj.material_slots, before["slots"]):
        s.material = bpy.data.materials[orig] if orig else None
    while len(me.materials) > len(before["slots"]):
        me.materials.pop()
    for m in report["materials"]:
        bpy.data.materials.remove(bpy.data.materials[m])
    for i in report["images"]:
        bpy.data.images.remove(bpy.data.images[i])
    me.uv_layers.remove(me.uv_layers[report["uv_map"]])
    me.uv_layers.active = me.uv_layers[before["uv_active"]]
    for uv in me.uv_layers:
        if uv.name in before["uv_render"]:
            uv.active_render = True
    after = H.object_state(name)
    assert after == before, _diff(before, after)


def save_beside_blend(pkg):
    """storage='SAVE' writes PNG files beside the saved .blend."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    with scratch_folder("atlas_save_") as tmp:
        blend = os.path.join(tmp, "scene.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)
        obj = bpy.data.objects[obj.name]
        before = H.object_state(obj.name)
        report = pkg.defragment(obj, storage="SAVE")
        check_result(obj.name, before, report)
        for name in report["images"]:
            img = bpy.data.images[name]
            path = bpy.path.abspath(img.filepath)
            assert img.packed_file is None and os.path.dirname(path) == tmp and path.endswith(".png"), path
            a = np.empty(len(img.pixels), np.float32)
            img.pixels.foreach_get(a)
            img.reload()
            b = np.empty(len(img.pixels), np.float32)
            img.pixels.foreach_get(b)
            assert np.array_equal(a, b), f"{name} differs after reload from {path}"
        files = sorted(os.listdir(tmp))
        _failed_write_leaves_no_file(pkg, bpy.data.objects[obj.name], tmp)
        assert sorted(os.listdir(tmp)) == files
        # A folder relative to the .blend ('//'), as Blender's file fields give it.
        # ... and a plain relative one, taken from the .blend's folder too.
        for folder in ("//textures", "maps"):
            report = pkg.defragment(bpy.data.objects[obj.name], storage="SAVE", image_dir=folder)
            written = {os.path.basename(bpy.path.abspath(bpy.data.images[n].filepath)) for n in report["images"]}
            assert written and written <= set(os.listdir(os.path.join(tmp, folder.lstrip("/")))), written
        return {"files": files}


def _failed_write_leaves_no_file(pkg, obj, folder):
    """A write that fails after its images were saved takes them away again
    (and Blender's RuntimeError comes out as DefragError)."""
    before, files = H.object_state(obj.name), set(os.listdir(folder))
    write_bpy = pkg.write_bpy
    kept = write_bpy._write_uv_map

    def fail(*args):
        new = set(os.listdir(folder)) - files
        assert any(f.endswith(".png") for f in new), "no image written before the failure"
        raise RuntimeError("simulated failure after the images were saved")

    write_bpy._write_uv_map = fail
    try:
        with _raises(pkg.DefragError):
            pkg.defragment(obj, storage="SAVE", image_dir=folder)
    finally:
        write_bpy._write_uv_map = kept
    after = H.object_state(obj.name)
    assert after == before, _diff(before, after)
    assert set(os.listdir(folder)) == files, set(os.listdir(folder)) ^ files


def world_scale_density(pkg):
    """texels_per_unit counts per unit of the surface in the scene: an object
    scaled (uniformly and turned, or along one axis) gets its new texels by
    its world-space area."""
    densities = {}
    for scale, turn in (((2.0, 2.0, 2.0), 0.5), ((1.0, 2.0, 1.0), 0.0)):
        H.reset()
        obj = H.import_model(H.model_path("tetra"))
        obj.scale, obj.rotation_euler[2] = scale, turn
        bpy.context.view_layer.update()
        # A UV map name near Blender's limit of 63 bytes: the new map's is cut
        # short, and moving it to the front must not depend on longer names.
        obj.data.uv_layers.active.name = "u" * 60
        texels_per_unit = 512.0
        report = pkg.defragment(obj, texels_per_unit=texels_per_unit)
        density = _texels_per_world_unit(obj, report)
        assert abs(density / texels_per_unit - 1) < 0.05, (scale, density, texels_per_unit)
        me = obj.data
        assert me.uv_layers[0].name == report["uv_map"] and "u" * 60 in me.uv_layers, [u.name for u in me.uv_layers]
        densities[str(scale)] = float(density)
    return densities


def _texels_per_world_unit(obj, report) -> float:
    """sqrt(texel area / world-space area) of obj's new UV map (one page)."""
    me = obj.data
    me.calc_loop_triangles()
    n = len(me.loop_triangles)
    loops = np.empty(3 * n, np.int32)
    me.loop_triangles.foreach_get("loops", loops)
    uv = np.empty(2 * len(me.loops), np.float32)
    me.uv_layers[report["uv_map"]].data.foreach_get("uv", uv)
    sizes = {bpy.data.images[name].size[:] for name in report["images"]}
    assert len(sizes) == 1, sizes  # one page: UV area times its texels is texel area
    (w, h), = sizes
    t = uv.reshape(-1, 2)[loops].reshape(n, 3, 2).astype(np.float64) * (w, h)
    texel_area = 0.5 * np.abs(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])).sum()
    co = np.empty(3 * len(me.vertices), np.float32)
    me.vertices.foreach_get("co", co)
    verts = np.empty(3 * n, np.int32)
    me.loop_triangles.foreach_get("vertices", verts)
    world = co.reshape(-1, 3).astype(np.float64) @ np.array(obj.matrix_world.to_3x3(), np.float64).T
    p = world[verts].reshape(n, 3, 3)
    world_area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum()
    return float(np.sqrt(texel_area / world_area))


def cancel_leaves_nothing(pkg):
    """Cancelling (as Esc does, from another thread) raises DefragCancelled
    and changes nothing."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    name = obj.name
    before = H.object_state(name)
    from importlib import import_module
    native = import_module(pkg.__name__ + "._native")
    token = native.CancelToken()
    seen = []

    def progress(stage, fraction):
        seen.append((stage, fraction))
        if len(seen) == 3:
            threading.Thread(target=token.cancel).start()

    try:
        pkg.defragment(obj, progress=progress, cancel=token)
    except pkg.DefragCancelled:
        pass
    else:
        raise AssertionError("not cancelled")
    assert seen, "no progress reported"
    after = H.object_state(name)
    assert after == before, _diff(before, after)
    # The operator's worker thread path: the same, through operators._Run.
    settings = pkg.api.Settings.from_kwargs()
    read = pkg.api.prepare(bpy.data.objects[name], settings)
    token = native.CancelToken()
    token.cancel()
    run = pkg.operators._Run(read, settings, token)
    t = threading.Thread(target=run.work)
    t.start()
    t.join(120)
    assert isinstance(run.error, pkg.DefragCancelled), repr(run.error)
    assert H.object_state(name) == before


def prepared(pkg, model):
    """A fresh scene with one model, read for a default run: (obj, name,
    state before, settings, what api.prepare read)."""
    H.reset()
    obj = H.import_model(H.model_path(model))
    name = obj.name
    before = H.object_state(name)
    settings = pkg.api.Settings.from_kwargs()
    return obj, name, before, settings, pkg.api.prepare(obj, settings)


def worker_thread_run(pkg):
    """The modal operator's worker: computes off the main thread, then writes.
    Its images' pixels read on the main thread while the worker runs the
    layout (_Run.start) give the same result as pixels read first."""
    obj, name, before, settings, read = prepared(pkg, "tetra")
    run = pkg.operators._Run(read, settings, pkg.operators._native_token())
    t = threading.Thread(target=run.work)
    t.start()
    t.join(600)
    assert run.error is None, repr(run.error)
    assert run.fraction == 1.0, run.fraction
    later = pkg.api.prepare(obj, settings, pixels_later=True)
    assert all(isinstance(i, pkg.read_bpy.PendingImage) for i in later.job.images.values())
    overlapped = pkg.operators._Run(later, settings, pkg.operators._native_token())
    overlapped.start()
    overlapped.thread.join(600)
    assert overlapped.error is None, repr(overlapped.error)
    assert np.array_equal(overlapped.result.uvs, run.result.uvs)
    assert [i.pixels.tobytes() for i in overlapped.result.images] == [i.pixels.tobytes() for i in run.result.images]
    report = pkg.api.finish(bpy.data.objects[name], read, run.result, settings)
    check_result(name, before, report)


def identity_result(pkg, read):
    """A JobResult that keeps the layout and copies every source image."""
    job = read.job
    sizes = pkg.job.page_sizes_of(job)
    images = []
    for p, page in enumerate(job.pages):
        for m in page.maps:
            src = job.images[m.image]
            images.append(pkg.job.OutputImage(page=p, role=m.role, source=m.image, pixels=src.pixels.copy(),
                                              colorspace=src.colorspace, is_float=src.is_float,
                                              alpha_mode=src.alpha_mode))
    return pkg.job.JobResult(uvs=job.mesh.uvs.copy(), face_page=job.mesh.face_page.copy(), page_sizes=sizes,
                             page_group=np.array([p.group for p in job.pages], np.int32), images=images,
                             report={"charts_before": 1, "charts_after": 1})


def material_index_past_the_slots_keeps_drawing_with_the_last(pkg):
    """A face whose material_index is past the last slot draws with the last
    slot. New pages append slots: such a face on the first page must still
    draw with its own material, not the slot a new page appended."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    me = obj.data
    past = np.full(len(me.polygons), len(obj.material_slots), np.int32)
    me.polygons.foreach_set("material_index", past)
    read = pkg.api.prepare(obj, pkg.api.Settings.from_kwargs())
    result = identity_result(pkg, read)
    # The same layout on two pages: the second half of the faces on page 1.
    result.face_page[len(result.face_page) // 2:] = 1
    result.page_sizes = np.repeat(result.page_sizes, 2, axis=0)
    result.page_group = np.zeros(2, np.int32)
    result.images += [pkg.job.OutputImage(page=1, role=i.role, source=i.source, pixels=i.pixels.copy(),
                                          colorspace=i.colorspace, is_float=i.is_float, alpha_mode=i.alpha_mode)
                      for i in result.images]
    slots = len(obj.material_slots)
    pkg.api.finish(obj, read, result, pkg.api.Settings.from_kwargs())
    index = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("material_index", index)
    assert len(obj.material_slots) == slots + 1
    first = result.face_page[np.searchsorted(read.tri_polygons, np.arange(len(me.polygons)))] == 0
    assert (index[first] == slots - 1).all() and (index[~first] == slots).all(), np.bincount(index)


def write_identity_layout(pkg):
    """Writing a result: new map, images, materials; nothing old modified."""
    obj, name, before, settings, read = prepared(pkg, "tetra")
    result = identity_result(pkg, read)
    report = pkg.api.finish(obj, read, result, settings)
    assert report["uv_map"] == "UVMap_defrag"
    assert report["images"] == ["textured_0_v2_defrag"]
    me = bpy.data.objects[name].data
    # Same layout -> same UVs; same pixels after the byte round trip.
    assert H.uv_hash(me, "UVMap_defrag") == before["uv_hash"]["UVMap"]
    new = bpy.data.images["textured_0_v2_defrag"]
    old = bpy.data.images["textured_0_v2.jpg"]
    assert new.packed_file is not None and new.source == "FILE"
    a = np.empty(len(old.pixels), np.float32)
    b = np.empty(len(new.pixels), np.float32)
    old.pixels.foreach_get(a)
    new.pixels.foreach_get(b)
    assert np.array_equal(a, b)
    with _raises(AssertionError, match="the new UV map equals the old one"):  # the check notices it
        check_result(name, before, report)
    mat = bpy.data.objects[name].material_slots[0].material
    tex = mat.node_tree.nodes["Image Texture"]
    assert tex.image == new and H.vector_uv_map(tex) == "UVMap_defrag"
    # The unloadable normal map keeps reading the old map explicitly.
    assert H.vector_uv_map(mat.node_tree.nodes["Image Texture.001"]) == "UVMap"
    assert mat.node_tree.nodes["Normal Map"].uv_map == "UVMap"
    for n, st in before["image_state"].items():
        assert H.image_state(bpy.data.images[n]) == st


# --------------------------------------------------------------------------- reading PNG files


def filtered_png(pixels, chunks=()) -> bytes:
    """PNG bytes of (H, W, 1, 3 or 4) uint8 pixels (top row first), row y
    filtered with type y % 5 (None, Sub, Up, Average, Paeth: PNG spec 9.2),
    the chunks (type, data) given placed before the pixel data."""
    import io
    import zlib

    from atlas_defrag import png_files

    h, w, c = pixels.shape
    rows = pixels.reshape(h, w * c).astype(np.int32)
    above = np.vstack([np.zeros((1, w * c), np.int32), rows[:-1]])
    left = np.hstack([np.zeros((h, c), np.int32), rows[:, :-c]])
    upper_left = np.hstack([np.zeros((h, c), np.int32), above[:, :-c]])
    p = left + above - upper_left
    pa, pb, pc = np.abs(p - left), np.abs(p - above), np.abs(p - upper_left)
    paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, above, upper_left))
    predictions = [np.zeros_like(rows), left, above, (left + above) // 2, paeth]
    scanlines = np.empty((h, 1 + w * c), np.uint8)
    for y in range(h):
        scanlines[y, 0] = y % 5
        scanlines[y, 1:] = (rows[y] - predictions[y % 5][y]) & 255
    header = png_files._IHDR.pack(w, h, 8, png_files._COLOUR_TYPE[c], 0, 0, 0)
    out = io.BytesIO()
    out.write(png_files.SIGNATURE)
    for kind, data in [(b"IHDR", header)] + list(chunks) + [(b"IDAT", zlib.compress(scanlines.tobytes())),
                                                           (b"IEND", b"")]:
        png_files._write_chunk(out, kind, data)
    return out.getvalue()


def png_read_from_file(pkg):
    """An 8-bit RGB or RGBA PNG that Blender has not loaded, on disk or
    packed, is decoded from its bytes without Blender loading it, to exactly
    the pixels Blender's own route gives, under every alpha mode it is
    decoded for (RGBA under premultiplied or ignored alpha is left to
    Blender), with the file's channels; a loaded one, or one with a tRNS
    chunk, goes through Blender, and one cut short is skipped as Blender
    skips it. Blender's route gives a grey file's one channel too, unless
    its pixels were edited."""
    rb = pkg.read_bpy
    rng = np.random.default_rng(5)
    decoded = set()
    with scratch_folder("png_read") as folder:
        for channels in (3, 4):
            pixels = rng.integers(0, 256, (29, 41, channels)).astype(np.uint8)
            path = os.path.join(folder, f"channels{channels}.png")
            with open(path, "wb") as f:
                f.write(filtered_png(pixels))
            for mode in ("STRAIGHT", "CHANNEL_PACKED", "PREMUL", "NONE"):
                img = bpy.data.images.load(path, check_existing=False)
                img.alpha_mode = mode
                if not rb._plain_png(img):
                    bpy.data.images.remove(img)
                    continue
                decoded.add((channels, mode))
                assert rb._check_image(img, "m") is None and not img.has_data
                ours = pkg.png_files.decode_png_or_none(rb._file_bytes(img))
                img.pack()
                assert rb._plain_png(img) and np.array_equal(pkg.png_files.decode_png_or_none(rb._file_bytes(img)), ours)
                blenders = rb.read_pixels(img)
                assert ours.shape == blenders.shape == (29, 41, channels), (channels, mode)
                assert np.array_equal(ours, blenders), (channels, mode)
                assert np.array_equal(ours[::-1], pixels)
                assert img.has_data and not rb._plain_png(img)  # loaded: Blender's pixels count
                bpy.data.images.remove(img)
        assert decoded == {(3, "STRAIGHT"), (3, "CHANNEL_PACKED"), (3, "PREMUL"), (3, "NONE"),
                           (4, "STRAIGHT"), (4, "CHANNEL_PACKED")}, decoded
        grey = rng.integers(0, 256, (29, 41, 1)).astype(np.uint8)
        path = os.path.join(folder, "grey.png")
        with open(path, "wb") as f:
            f.write(filtered_png(grey))
        img = bpy.data.images.load(path, check_existing=False)
        assert not rb._plain_png(img) and np.array_equal(rb.read_pixels(img)[::-1], grey)
        edited = np.empty(len(img.pixels), np.float32)  # one texel painted red: no longer grey
        img.pixels.foreach_get(edited)
        edited[:4] = (1, 0, 0, 1)
        img.pixels.foreach_set(edited)
        assert img.depth == 8 and rb.read_pixels(img).shape == (29, 41, 4)
        bpy.data.images.remove(img)
        _read_images_mixes_routes(pkg, folder, rng)


def _read_images_mixes_routes(pkg, folder, rng):
    """One read of a plain PNG, a PNG with a tRNS chunk (Blender turns its
    colour key into alpha) and a PNG cut short (Blender skips it, as before):
    the plain one decoded without loading it, the keyed one read by Blender."""
    rb, job = pkg.read_bpy, pkg.job
    files = {}
    for name, chunks in (("plain", ()), ("keyed", [(b"tRNS", bytes(6))])):
        path = os.path.join(folder, f"{name}.png")
        with open(path, "wb") as f:
            f.write(filtered_png(rng.integers(0, 256, (8, 8, 3)).astype(np.uint8), chunks))
        files[name] = bpy.data.images.load(path, check_existing=False)
    assert rb._plain_png(files["plain"]) and rb._plain_png(files["keyed"])  # the header cannot tell
    assert pkg.png_files.decode_png_or_none(rb._file_bytes(files["keyed"])) is None
    page = job.SourcePage([job.ImageMap("base_color", files["plain"].name),
                           job.ImageMap("roughness", files["keyed"].name)], 0)
    read = rb._read_images([page])
    assert not files["plain"].has_data and not files["keyed"].has_data  # pixels pending, sizes known
    assert read[files["plain"].name].size == read[files["keyed"].name].size == (8, 8)
    for img in files.values():  # asked for on the main thread: read there
        assert read[img.name].pixels.dtype == np.uint8 and not read[img.name].is_float
    assert not files["plain"].has_data and files["keyed"].has_data
    assert np.array_equal(read[files["keyed"].name].pixels, rb.read_pixels(files["keyed"]))
    cut = os.path.join(folder, "cut.png")
    with open(files["plain"].filepath, "rb") as f:
        whole = f.read()
    with open(cut, "wb") as f:
        f.write(whole[:-20])
    img = bpy.data.images.load(cut, check_existing=False)
    assert not rb._plain_png(img) and rb._check_image(img, "m") is not None  # skipped, with a warning
    for img in list(files.values()) + [img]:
        bpy.data.images.remove(img)


# --------------------------------------------------------------------------- export, save


def _pixels(img) -> np.ndarray:
    """(H, W, 4) float32 pixels of an image."""
    arr = np.empty(img.size[0] * img.size[1] * img.channels, dtype=np.float32)
    img.pixels.foreach_get(arr)
    return _as_rgba(arr.reshape(img.size[1], img.size[0], img.channels))


def _as_rgba(px):
    if px.shape[2] == 4:
        return px
    out = np.ones(px.shape[:2] + (4,), np.float32)
    out[..., :px.shape[2]] = px
    return out


def _base_color_image(mat):
    """The image feeding Base Color, straight or through other nodes."""
    if mat is None or mat.node_tree is None:
        return None
    for node in H.image_nodes(mat):
        if node.image is None:
            continue
        targets = [lk.to_socket.name for out in node.outputs for lk in out.links]
        if any(t in ("Base Color", "Color", "Color1", "A", "Subsurface Color") for t in targets) \
                or not targets:
            return node.image
    return None


def face_colours(obj, uv_name):
    """(polygons, 3) RGB at each polygon's UV centroid on map uv_name, through the
    base colour image of its material; NaN for polygons without one."""
    me = obj.data
    uv = np.empty(len(me.loops) * 2, np.float32)
    me.uv_layers[uv_name].data.foreach_get("uv", uv)
    uv = uv.reshape(-1, 2)
    starts = np.empty(len(me.polygons), np.int32)
    counts = np.empty(len(me.polygons), np.int32)
    mats = np.empty(len(me.polygons), np.int32)
    me.polygons.foreach_get("loop_start", starts)
    me.polygons.foreach_get("loop_total", counts)
    me.polygons.foreach_get("material_index", mats)
    centre = np.add.reduceat(uv, starts) / counts[:, None]
    out = np.full((len(me.polygons), 3), np.nan, np.float32)
    for slot, ms in enumerate(obj.material_slots):
        img = _base_color_image(ms.material)
        faces = mats == slot
        if img is None or not faces.any():
            continue
        px = _pixels(img)
        h, w = px.shape[:2]
        c = centre[faces] % 1.0
        x = np.clip((c[:, 0] * w).astype(int), 0, w - 1)
        y = np.clip((c[:, 1] * h).astype(int), 0, h - 1)
        out[faces] = px[y, x, :3]
    return out


def _import_any(path):
    """Imports an exported model (FBX or OBJ) into an empty scene; its largest mesh."""
    H.reset()
    if path.endswith(".fbx"):
        bpy.ops.import_scene.fbx(filepath=path)
    else:
        H.import_model(path)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    return max(meshes, key=lambda o: len(o.data.polygons))


def _export(path, obj):
    H.make_active(obj)
    if path.endswith(".fbx"):
        bpy.ops.export_scene.fbx(filepath=path, use_selection=True, path_mode="COPY", embed_textures=True)
    elif hasattr(bpy.ops.wm, "obj_export"):
        bpy.ops.wm.obj_export(filepath=path, export_selected_objects=True, path_mode="COPY")
    else:
        bpy.ops.export_scene.obj(filepath=path, use_selection=True, path_mode="COPY")


def export_round_trip(pkg, model, ext):
    """Operator with its defaults, export, re-import: the colour per face
    through the re-imported first UV map and its texture is the original
    colour (mean error <= 4/255). FBX embeds the packed images; OBJ takes
    image files, so it runs with 'Save Beside .blend' (and with the default
    'Pack in .blend' its MTL still names the new texture)."""
    H.reset()
    obj = H.import_model(H.model_path(model))
    name = obj.name
    before = face_colours(obj, obj.data.uv_layers.active.name)
    with scratch_folder(f"atlas_{ext}_") as folder:
        path = os.path.join(folder, "model." + ext)
        if ext == "obj":
            H.undo_push("before")
            assert run_operator(pkg, undo=True) == {"FINISHED"}
            _export(path, bpy.data.objects[name])
            mtl = open(os.path.join(folder, "model.mtl")).read()
            assert "map_Kd texture_1001_defrag.png" in mtl, mtl[:500]
            H.undo()
            bpy.ops.wm.save_as_mainfile(filepath=os.path.join(folder, "scene.blend"))
            assert run_operator(pkg, storage="SAVE") == {"FINISHED"}
        else:
            assert run_operator(pkg) == {"FINISHED"}
        obj = bpy.data.objects[name]
        assert obj.data.uv_layers[0].name.endswith("_defrag"), [u.name for u in obj.data.uv_layers]
        _export(path, obj)
        again = _import_any(path)
        assert len(again.data.polygons) == len(before), (len(again.data.polygons), len(before))
        after = face_colours(again, again.data.uv_layers[0].name)
        both = ~np.isnan(before[:, 0]) & ~np.isnan(after[:, 0])
        assert both.mean() > 0.9, f"only {both.mean():.2f} of the faces have a texture after the round trip"
        error = float(np.abs(after[both] - before[both]).mean() * 255)
        assert error <= 4.0, f"mean error {error:.1f}/255 after the {ext} round trip"
        return {"mean_error_255": error, "faces": int(both.sum())}


def save_reopen(pkg, model="smithsonian"):
    """Save and reopen after a run with duplicated materials: the original
    images (embedded in the GLB) and materials and the new ones keep their pixels."""
    H.reset()
    obj = H.import_model(H.model_path(model))
    name = obj.name
    originals = {i.name: H.image_state(i)["pixels"] for i in bpy.data.images if i.size[0] > 0}
    old_materials = [s.material.name for s in obj.material_slots]
    report = pkg.defragment(obj, duplicate_materials=True)
    new = {n: H.image_state(bpy.data.images[n])["pixels"] for n in report["images"]}
    with scratch_folder("atlas_reopen_") as folder:
        blend = os.path.join(folder, "scene.blend")
        bpy.ops.wm.save_as_mainfile(filepath=blend)
        bpy.ops.wm.open_mainfile(filepath=blend)
        for n, pixels in list(originals.items()) + list(new.items()):
            assert n in bpy.data.images, f"image {n} lost after save and reopen"
            assert H.image_state(bpy.data.images[n])["pixels"] == pixels, f"image {n} changed after reopen"
        for m in old_materials + report["materials"]:
            assert m in bpy.data.materials, f"material {m} lost after save and reopen"
        assert bpy.data.objects[name].data.uv_layers[0].name == report["uv_map"]
        return {"images": sorted(originals) + sorted(new)}


def several_objects(pkg):
    """Two selected meshes: each gets its own new map and images, and the
    outcome reports both."""
    H.reset()
    a = H.import_model(H.model_path("tetra"))
    b = H.textured_plane(name="Second")
    states = {o.name: H.object_state(o.name) for o in (a, b)}
    H.make_active(a)
    b.select_set(True)
    assert run_operator(pkg) == {"FINISHED"}
    for n, before in states.items():
        check_result(n, before, None)
    message = pkg.operators.last_outcome["message"]
    for n in states:
        assert f"Defragmented '{n}'" in message, message
    assert "New images:" in message and "x" in message, message
    # The scan's page keeps the full padding; the plane's small page gets less.
    assert "(4 texels of padding)" in message and "(2 texels of padding)" in message, message
    return {"message": message}


def one_atlas_for_all_selected(pkg):
    """One Atlas for All Selected: two meshes (a scan and a plane) share one
    set of new images; their new UV maps together cover no texel twice; the
    outcome reports each object; one undo takes both back."""
    H.reset()
    a = H.import_model(H.model_path("tetra"))
    b = H.textured_plane(name="Second")
    names = [a.name, b.name]
    states = {n: H.object_state(n) for n in names}
    H.make_active(a)
    b.select_set(True)
    H.undo_push("before")
    assert run_operator(pkg, undo=True, one_atlas=True) == {"FINISHED"}
    for n, before in states.items():
        check_result(n, before, None)
    reports = pkg.operators.last_outcome["report"]
    assert [r["object"] for r in reports] == names, [r["object"] for r in reports]
    assert all(r["atlas_objects"] == names and r["images"] == reports[0]["images"] for r in reports), reports
    assert set(reports[0]["pages_used"]) & set(reports[1]["pages_used"]), "the objects share no page"
    message = pkg.operators.last_outcome["message"]
    assert f"Defragmented '{names[0]}' (one atlas with '{names[1]}')" in message, message
    assert f"Defragmented '{names[1]}' (one atlas with '{names[0]}')" in message, message
    m = _shared_atlas_measures(pkg, names, reports[0]["uv_map"])
    assert m["overlap_texels"] == 0 and m["flipped_faces"] == 0, m
    H.undo()
    for n, before in states.items():
        assert H.object_state(n) == before, _diff(before, H.object_state(n))
    return {"new": m}


def one_atlas_shared_material(pkg):
    """One atlas for two objects that share a material but not their UV map's
    name: each ends with a material that reads its own new UV map."""
    H.reset()
    a = H.textured_plane(name="First")
    b = H.textured_plane(name="Second")
    b.data.materials[0] = a.data.materials[0]
    b.data.uv_layers[0].name = "OtherUV"
    H.make_active(a)
    b.select_set(True)
    assert run_operator(pkg, one_atlas=True) == {"FINISHED"}
    read_maps = {}
    for obj in (a, b):
        maps = {H.vector_uv_map(n) for n in H.image_nodes(obj.material_slots[0].material)}
        new_map = obj.data.uv_layers.active.name
        assert new_map.endswith("_defrag") and maps == {new_map}, (obj.name, maps, new_map)
        read_maps[obj.name] = sorted(maps)
    assert a.material_slots[0].material != b.material_slots[0].material
    return read_maps


def _planes_sharing_a_material(first: str, second: str):
    """(first, second, their material) in a fresh scene, first active and alone selected."""
    H.reset()
    a = H.textured_plane(name=first)
    b = H.textured_plane(name=second)
    b.data.materials[0] = a.data.materials[0]
    H.make_active(a)
    return a, b, a.data.materials[0]


def shared_material_one_at_a_time(pkg):
    """Two objects that share a material, each given its own atlas: both are
    done, each through a copy of the material that reads its own new UV map,
    and the original material is left as it was."""
    a, b, shared = _planes_sharing_a_material("First", "Second")
    b.select_set(True)
    before = {n.name: (n.image.name, H.vector_uv_map(n)) for n in H.image_nodes(shared)}
    assert run_operator(pkg) == {"FINISHED"}, pkg.operators.last_outcome
    message = pkg.operators.last_outcome["message"]
    assert "Defragmented 'First'" in message and "Defragmented 'Second'" in message, message
    materials = set()
    for obj in (a, b):
        mat = obj.material_slots[0].material
        materials.add(mat.name)
        maps = {H.vector_uv_map(n) for n in H.image_nodes(mat)}
        new_map = obj.data.uv_layers.active.name
        assert new_map.endswith("_defrag") and maps == {new_map}, (obj.name, maps, new_map)
    assert len(materials) == 2 and shared.name not in materials, materials
    assert {n.name: (n.image.name, H.vector_uv_map(n)) for n in H.image_nodes(shared)} == before
    return sorted(materials)


def material_shared_with_an_unselected_object(pkg):
    """A material that an object not selected (drawing another mesh) also
    uses is copied for the object done, so that the other keeps rendering
    as it did; objects drawing the same mesh need no copy."""
    a, b, shared = _planes_sharing_a_material("Done", "Untouched")
    before = H.tree_state(shared)
    assert run_operator(pkg) == {"FINISHED"}, pkg.operators.last_outcome
    assert a.material_slots[0].material != shared and H.tree_state(shared) == before
    assert b.material_slots[0].material == shared
    solo = H.textured_plane(name="Alone")
    bpy.context.collection.objects.link(solo.copy())  # a linked duplicate: it draws Alone's mesh
    H.make_active(solo)
    mat = solo.material_slots[0].material
    assert run_operator(pkg) == {"FINISHED"} and solo.material_slots[0].material == mat
    a, b, shared = _planes_sharing_a_material("ByScript", "Untouched")  # the Python entry alike
    before = H.tree_state(shared)
    pkg.defragment(a)
    assert a.material_slots[0].material != shared and H.tree_state(shared) == before


def linked_duplicate_with_its_own_material_is_named(pkg):
    """Two selected objects drawing one mesh, the second through a material
    linked to the object: the mesh is done once, for the active object, and
    the report names the other, whose material still reads the old map."""
    H.reset()
    first = H.textured_plane(name="First")
    second = first.copy()
    bpy.context.collection.objects.link(second)
    own = first.material_slots[0].material.copy()
    second.material_slots[0].link = "OBJECT"
    second.material_slots[0].material = own
    H.make_active(first)
    second.select_set(True)
    assert run_operator(pkg) == {"FINISHED"}, pkg.operators.last_outcome
    warnings = pkg.operators.last_outcome["report"][0]["warnings"]
    assert any(f"'{second.name}' shares its mesh with '{first.name}'" in w and own.name in w for w in warnings), \
        warnings
    assert {H.vector_uv_map(n) for n in H.image_nodes(own)} <= {None, "UVMap"}, H.tree_state(own)


def planes_reading_their_own_maps():
    """Two selected planes with two UV maps each, the first active: the
    first's image reads its second map (a UV Map node names it), the
    second's its render-active first map. Returns (first, second, the map
    the first's image reads, the map the second's reads)."""
    first, second = H.textured_plane(name="First", uv_maps=2), H.textured_plane(name="Second", uv_maps=2)
    for obj in (first, second):
        obj.data.uv_layers.active = obj.data.uv_layers[0]
    scan, own = first.data.uv_layers[1].name, second.data.uv_layers[0].name
    mat = first.material_slots[0].material
    node = mat.node_tree.nodes.new("ShaderNodeUVMap")
    node.uv_map = scan
    mat.node_tree.links.new(node.outputs["UV"], H.image_nodes(mat)[0].inputs["Vector"])
    H.make_active(first)
    second.select_set(True)
    return first, second, scan, own


def an_image_reading_another_map_decides_the_default_map(pkg):
    """The image reads a map that is not the active one, through a UV Map
    node: with no map named, the job (and the dialog's default) takes that
    map; the active map named instead is refused with the map the image
    reads in the message."""
    H.reset()
    obj, _, scan, _ = planes_reading_their_own_maps()
    H.make_active(obj)
    me = obj.data
    assert pkg.read_bpy.check_object(obj).name == scan
    error = _report_error(pkg, lambda: pkg.read_bpy.check_textures(obj, me.uv_layers[0].name))
    assert f"read UV map '{scan}'" in error, error
    assert run_operator(pkg) == {"FINISHED"}, pkg.operators.last_outcome
    report = pkg.operators.last_outcome["report"][0]
    assert report["source_uv_map"] == scan and report["uv_map"] == f"{scan}_defrag", report
    return {"uv_map": report["uv_map"]}


def the_base_colours_map_is_the_default_among_several(pkg):
    """Images reading two maps, neither the active one: the default is the
    base colour's map, and the emission image on the other is named as left
    unchanged. A UV Map node naming a map the mesh lacks is named as such."""
    H.reset()
    obj = H.textured_plane(name="Layers", uv_maps=3)
    me, mat = obj.data, obj.material_slots[0].material
    me.uv_layers.active = me.uv_layers[0]
    tree, colour = mat.node_tree, H.image_nodes(mat)[0]
    glow = tree.nodes.new("ShaderNodeTexImage")
    glow.image = colour.image.copy()
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tree.links.new(glow.outputs["Color"], bsdf.inputs["Emission Color" if bpy.app.version >= (4, 0, 0) else "Emission"])
    for image_node, layer in ((colour, me.uv_layers[2]), (glow, me.uv_layers[1])):
        node = tree.nodes.new("ShaderNodeUVMap")
        node.uv_map = layer.name
        tree.links.new(node.outputs["UV"], image_node.inputs["Vector"])
    assert pkg.read_bpy.check_object(obj).name == me.uv_layers[2].name
    report = pkg.defragment(obj)
    assert any(f"'{glow.image.name}'" in w and "left unchanged" in w for w in report["warnings"]), report["warnings"]
    H.reset()
    obj = H.textured_plane(name="Ghostly")
    mat = obj.material_slots[0].material
    node = mat.node_tree.nodes.new("ShaderNodeUVMap")
    node.uv_map = "Ghost"
    mat.node_tree.links.new(node.outputs["UV"], H.image_nodes(mat)[0].inputs["Vector"])
    error = _report_error(pkg, lambda: pkg.read_bpy.check_textures(obj))
    assert "'Ghost', which the mesh has no map of" in error, error
    return {}


def an_object_linked_slot_is_not_another_user(pkg):
    """A material in an object-linked slot, the mesh's slot holding it too,
    is used by this object alone: no warning that other objects use it, as
    there is when another object's mesh holds it."""
    def run(shared):
        H.reset()
        obj = H.textured_plane(name="Own")
        mat = obj.material_slots[0].material
        obj.material_slots[0].link = "OBJECT"
        obj.material_slots[0].material = mat
        if shared:
            H.textured_plane(name="Other").data.materials[0] = mat
        report = pkg.defragment(obj, duplicate_materials=False)
        return [w for w in report["warnings"] if "also used by other objects" in w]
    assert not run(shared=False)
    assert run(shared=True)
    return {}


def quads_stay_whole(pkg):
    """A quad sphere cut into many charts by Smart UV Project: the seam
    refinement moves a quad's two triangles together or not at all, so no
    polygon corner is split between charts (each holds one UV)."""
    H.reset()
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32)
    obj = bpy.context.active_object
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project(angle_limit=0.3)
    bpy.ops.object.mode_set(mode="OBJECT")
    plane = H.textured_plane(name="Source")  # its material: an image on Base Color
    obj.data.materials.append(plane.data.materials[0])
    report = pkg.defragment(obj)
    assert report["charts_before"] > 20 and report["charts_after"] < report["charts_before"], report
    assert not any("split between charts" in w for w in report["warnings"]), report["warnings"]
    return {"charts": [report["charts_before"], report["charts_after"]], "moved": report["refine_faces_moved"]}


def scan_quads_stay_whole(pkg):
    """The tetra scan joined into quads by Tris to Quads (UVs compared, so
    quads keep one chart): the cuts that open charts (relief cuts, cuts to a
    disk) run around the quads, so none is split between charts."""
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    H.make_active(obj)
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.mesh.tris_convert_to_quads(uvs=True)
    bpy.ops.object.mode_set(mode="OBJECT")
    quads = sum(len(p.vertices) == 4 for p in obj.data.polygons)
    report = pkg.defragment(obj)
    assert quads > 3000 and report["relief_cuts"] > 0, (quads, report["relief_cuts"])
    assert not any("split between charts" in w for w in report["warnings"]), report["warnings"]
    return {"quads": quads, "charts": [report["charts_before"], report["charts_after"]],
            "relief_cuts": report["relief_cuts"]}


def _shared_atlas_measures(pkg, names, uv_map):
    """_native.measure of the objects' new UV maps together, each face on the
    page of the new image its material now shows (pages by image name)."""
    from importlib import import_module
    native = import_module(pkg.__name__ + "._native")
    page_of_image, sizes = {}, []
    positions, triangles, uvs, face_page = [], [], [], []
    for k, n in enumerate(names):
        job = pkg.read_bpy.read(bpy.data.objects[n], uv_map).job
        local = []
        for page in job.pages:
            image = page.maps[0].image
            if image not in page_of_image:
                page_of_image[image] = len(sizes)
                sizes.append(bpy.data.images[image].size[:])
            local.append(page_of_image[image])
        local = np.array(local, np.int32)
        offset = sum(len(p) for p in positions)
        positions.append(job.mesh.positions + [10.0 * k, 0.0, 0.0])  # apart: equal positions weld
        triangles.append(job.mesh.triangles + offset)
        uvs.append(job.mesh.uvs)
        face_page.append(np.where(job.mesh.face_page >= 0, local[np.maximum(job.mesh.face_page, 0)], -1))
    pos, tri = np.concatenate(positions), np.concatenate(triangles).astype(np.int32)
    uv, fp = np.concatenate(uvs), np.concatenate(face_page).astype(np.int32)
    size = np.array(sizes, np.int32)
    return native.measure_atlas(pos, tri, uv, fp, size)


def several_objects_one_fails(pkg):
    """The second selected mesh has no image texture: the first is done, the
    error names what was done and the third mesh, not tried, and one undo
    takes it back."""
    H.reset()
    a = H.import_model(H.model_path("tetra"))
    name = a.name
    b = make_error_case_object("no_image_texture", "Bare")
    c = H.textured_plane(name="Third")
    before, third = H.object_state(name), H.object_state("Third")
    H.make_active(a)
    b.select_set(True)
    c.select_set(True)
    H.undo_push("before")
    try:
        run_operator(pkg, undo=True)
    except RuntimeError as exc:
        msg = str(exc)
    else:
        raise AssertionError("the operator did not report the second object's error")
    assert f"Done for '{name}'" in msg and "No image texture" in msg and "(not tried: Third)" in msg, msg
    now = H.object_state("Third")
    assert all(now[k] == third[k] for k in ("uv_maps", "uv_hash", "slots")), "the mesh not tried changed"
    check_result(name, before, None)
    H.undo()
    assert H.object_state(name) == before, _diff(before, H.object_state(name))


def make_error_case_object(case, name):
    """A plane with the problem of an error case, added to the current scene."""
    obj = H.textured_plane(name=name)
    if case == "no_image_texture":
        tree = obj.data.materials[0].node_tree
        for n in [n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage"]:
            tree.nodes.remove(n)
    return obj


def redo_asks_first(pkg):
    """Redo (Adjust Last Operation, here through ed.undo_redo) does not re-run
    the job unless Run Again is ticked; cancelled, it leaves the first result."""
    H.reset()
    obj = H.textured_plane()
    name = obj.name
    H.undo_push("before")
    assert run_operator(pkg, undo=True) == {"FINISHED"}
    first = H.object_state(name)
    outcome = pkg.operators.last_outcome
    outcome["status"] = None
    with H.undo_context():
        assert bpy.ops.ed.undo_redo() == {"CANCELLED"}
    assert outcome["status"] is None, outcome  # the job did not run
    assert H.object_state(name) == first, _diff(first, H.object_state(name))
    bpy.context.window_manager.operators[-1].properties.run_again = True
    with H.undo_context():
        assert bpy.ops.ed.undo_redo() == {"FINISHED"}
    assert outcome["status"] == "finished", outcome
    again = H.object_state(name)
    assert again["uv_maps"] == first["uv_maps"] and again["images"] == first["images"], _diff(first, again)


# --------------------------------------------------------------------------- errors

ERRORS = {
    "no_active_mesh": "No active mesh",
    "camera_active": "No active mesh",
    "no_uv_map": "no UV map",
    "no_image_texture": "No image texture",
    "eight_uv_maps": "8 UV maps",
    "udim": "UDIM",
    "no_faces": "has no faces",
    "nan_uvs": "UV map 'UVMap' of 'Plane' has coordinates that are not numbers (NaN or inf) on 1 face(s), face 4",
    "nan_positions": "'Plane' has 1 vertex(es) whose position is not a number (NaN or inf) in world space, vertex 5",
}


def make_error_case(case):
    """Builds the scene of an error case; returns the object (or None)."""
    H.reset()
    if case == "no_active_mesh":
        obj = H.textured_plane()
        H.make_active(None)
        return obj
    if case == "camera_active":
        obj = H.textured_plane()
        bpy.ops.object.camera_add()
        return obj
    if case == "no_uv_map":
        obj = H.textured_plane()
        obj.data.uv_layers.remove(obj.data.uv_layers[0])
        return obj
    if case == "no_image_texture":
        return make_error_case_object(case, "Plane")
    if case == "eight_uv_maps":
        return H.textured_plane(uv_maps=8)
    if case == "udim":
        return H.textured_plane(source="TILED")
    if case == "no_faces":  # a point cloud, as scanners also write: no faces, so no UVs either
        obj = H.textured_plane()
        me = bpy.data.meshes.new("Points")
        me.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [])
        me.materials.append(obj.data.materials[0])
        obj.data = me
        return obj
    if case == "nan_uvs":  # as a broken exporter or script leaves them
        obj = H.textured_plane()
        obj.data.uv_layers[0].data[obj.data.polygons[4].loop_start].uv = (float("nan"), 0.5)
        return obj
    if case == "nan_positions":
        obj = H.textured_plane()
        obj.data.vertices[5].co = (float("nan"), 0, 0)
        return obj
    raise ValueError(case)


def error_case(pkg, case):
    """The operator and the Python entry refuse with a clear message and
    change nothing."""
    obj = make_error_case(case)
    name = obj.name
    before = H.object_state(name)
    expected = ERRORS[case]
    try:
        run_operator(pkg)
    except RuntimeError as exc:
        msg = str(exc)
    else:
        raise AssertionError("the operator did not fail")
    assert expected.lower() in msg.lower(), msg
    target = bpy.context.view_layer.objects.active
    try:
        pkg.defragment(target)
    except pkg.DefragError as exc:
        msg2 = str(exc)
    else:
        raise AssertionError("defragment() did not fail")
    assert expected.lower() in msg2.lower(), msg2
    after = H.object_state(name)
    assert after == before, _diff(before, after)
    return msg


# --------------------------------------------------------------------------- utils


def _diff(a, b):
    keys = sorted(set(a) | set(b))
    out = []
    for k in keys:
        if a.get(k) != b.get(k):
            va, vb = a.get(k), b.get(k)
            if isinstance(va, dict) and isinstance(vb, dict):
                sub = [kk for kk in set(va) | set(vb) if va.get(kk) != vb.get(kk)]
                out.append(f"{k}: {sub[:5]} e.g. {[(va.get(s), vb.get(s)) for s in sub[:1]]}")
            else:
                out.append(f"{k}: {va!r} != {vb!r}")
    return "; ".join(out)[:2000]


def source_uv_warning_names_rendered_nodes(pkg):
    """The batch entry drops the source UV map from what it writes: it warns
    of the nodes that still render with that map, not of the unlinked ones
    the job leaves in the material."""
    import importlib

    batch = importlib.import_module(pkg.__name__ + ".batch")
    obj = H.textured_plane(name="DropUV")
    tree = obj.material_slots[0].material.node_tree
    source = obj.data.uv_layers[0].name
    obj.data.uv_layers.new(name="Other")
    tex = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    rendered = tree.nodes.new("ShaderNodeUVMap")
    rendered.uv_map = source
    tree.links.new(rendered.outputs["UV"], tex.inputs["Vector"])
    loose = tree.nodes.new("ShaderNodeUVMap")
    loose.uv_map = source
    report = {}
    batch._drop_source_uv(obj, source, report)
    assert [u.name for u in obj.data.uv_layers] == ["Other"]
    warning = " ".join(report.get("warnings", []))
    assert f"/{rendered.name}" in warning and f"/{loose.name}" not in warning, warning


def _report_error(pkg, fn) -> str:
    """The message of the DefragError, or the operator's error, fn raises."""
    try:
        fn()
    except (RuntimeError, pkg.DefragError) as exc:
        return str(exc)
    raise AssertionError("no error")


def operator_takes_what_it_is_told(pkg):
    """A deselected (or hidden) active object is not worked on, and the
    message says which; a UV map named that the mesh lacks is an error, a
    value a script gives an option with an Automatic toggle is used, and the
    Python entry refuses a string where a bool or a map name belongs.
    Nothing changes on a refusal."""
    H.reset()
    obj = H.textured_plane("Told")
    before = H.object_state(obj.name)
    obj.select_set(False)
    assert "is not selected" in _report_error(pkg, lambda: run_operator(pkg))
    obj.hide_set(True)
    assert "is hidden" in _report_error(pkg, lambda: run_operator(pkg))
    obj.hide_set(False)
    with pkg.compat.temp_override(bpy.context, selected_objects=[obj]):  # a script's override selects it
        assert "is not selected" not in _report_error(pkg, lambda: run_operator(pkg, uv_map="Scna"))
    obj.select_set(True)
    assert "no UV map named 'Scna'" in _report_error(pkg, lambda: run_operator(pkg, uv_map="Scna"))
    assert H.object_state(obj.name) == before
    for wrong in ({"duplicate_materials": "no"}, {"new_map_first": "False"}, {"uv_map": 123}):
        assert "must be a" in _report_error(pkg, lambda: pkg.defragment(obj, **wrong)), wrong
    assert H.object_state(obj.name) == before
    assert run_operator(pkg, fixed_page_size=256) == {"FINISHED"}
    new = [i for i in bpy.data.images if i.name.endswith("_defrag")]
    assert [tuple(i.size) for i in new] == [(256, 256)], [(i.name, tuple(i.size)) for i in new]
    # A script's 0 is automatic, and a value out of range is refused in words, not clamped.
    for wrong, words in (({"density_scale": 100.0}, "must be 0.01..16.0, not 100"), ({"padding": -3}, "not -3")):
        H.reset()
        H.textured_plane("Wrong")
        assert words in _report_error(pkg, lambda: run_operator(pkg, **wrong)), wrong
    H.reset()
    H.textured_plane("Zeros")
    assert run_operator(pkg, texels_per_unit=0.0, fixed_page_size=0, page_sides="POWER_OF_TWO") == {"FINISHED"}
    report = pkg.operators.last_outcome["report"][0]
    assert report["scale"] == 1.0 and not report["shrunk"], report


def image_settings_the_bake_cannot_follow_are_said(pkg):
    """An image node set to Extend where faces reach past the image, and an
    image linked from a library under the name of one in this file (the job
    finds images by name): each said in the report's warnings."""
    H.reset()
    obj = H.textured_plane("Past")
    tex = next(n for n in obj.material_slots[0].material.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    tex.extension = "EXTEND"
    for loop_uv in obj.data.uv_layers[0].data:
        loop_uv.uv = (loop_uv.uv[0] * 2, loop_uv.uv[1])
    report = pkg.defragment(obj)
    assert any("set to Extend" in w and "Past_tex" in w for w in report["warnings"]), report["warnings"]
    with scratch_folder("atlas_defrag_library_") as folder:
        H.reset()
        library = os.path.join(folder, "library.blend")
        shown = bpy.data.images.new("tex", 8, 8)
        shown.use_fake_user = True
        bpy.ops.wm.save_as_mainfile(filepath=library)
        H.reset()
        with bpy.data.libraries.load(library, link=True) as (_, linked):
            linked.images = ["tex"]
        obj = H.textured_plane("Linked")
        node = next(n for n in obj.material_slots[0].material.node_tree.nodes
                    if n.bl_idname == "ShaderNodeTexImage")
        bpy.data.images["Linked_tex"].name = "tex"  # the file's own image, under the linked one's name
        node.image = linked.images[0]
        assert "comes from the library 'library.blend'" in _report_error(pkg, lambda: pkg.defragment(obj))


def linear_float_images_keep_their_colour_space(pkg):
    """Blender saves a float image tagged Linear as sRGB values and tags it
    sRGB: the new image keeps the source's tag and its values."""
    H.reset()
    obj = H.textured_plane("Lin", image_size=(16, 16), float_buffer=True)
    src = bpy.data.images["Lin_tex"]
    linear = "Linear" if bpy.app.version < (4, 0, 0) else "Linear Rec.709"
    src.colorspace_settings.name = linear
    src.pixels.foreach_set(np.tile(np.array([0.2, 0.2, 0.2, 1], np.float32), 16 * 16))
    src.pack()
    report = pkg.defragment(obj, padding=0)
    new = bpy.data.images[report["images"][0]]
    values = np.empty(new.size[0] * new.size[1] * 4, np.float32)
    new.pixels.foreach_get(values)
    rgb = values.reshape(-1, 4)[:, :3]
    assert new.colorspace_settings.name == linear, new.colorspace_settings.name
    assert np.allclose(rgb[rgb.max(axis=1) > 0.01], 0.2, atol=1e-3), np.unique(rgb.round(3))


def premultiplied_byte_images_keep_their_colours(pkg):
    """An 8-bit PNG set to premultiplied alpha: Blender hands out its pixels
    straight, as they are baked; the new image shows the same colours (it
    was tagged premultiplied and showed them divided by alpha again)."""
    import importlib

    png_files = importlib.import_module(pkg.__name__ + ".png_files")
    H.reset()
    obj = H.textured_plane("Premul", image_size=(16, 16))
    colour, alpha = np.array([0.2, 0.4, 0.6]), 0.25
    texel = np.rint(np.append(colour * alpha, alpha) * 255).astype(np.uint8)  # premultiplied in the file
    with scratch_folder("atlas_defrag_premul_") as folder:
        path = os.path.join(folder, "premul.png")
        with open(path, "wb") as f:
            f.write(png_files.encode_png(np.tile(texel, (16, 16, 1))))
        src = bpy.data.images.load(path)
        src.alpha_mode = "PREMUL"
        src.pack()
        H.image_nodes(obj.material_slots[0].material)[0].image = src
        report = pkg.defragment(obj, padding=0)
    new = bpy.data.images[report["images"][0]]
    values = np.empty(new.size[0] * new.size[1] * 4, np.float32)
    new.pixels.foreach_get(values)
    shown = values.reshape(-1, 4)
    shown = shown[shown[:, 3] > 0.2]
    assert len(shown) and np.allclose(shown[:, :3], colour, atol=0.02), np.unique(shown.round(2), axis=0)[:4]


def a_failed_save_takes_back_its_folders(pkg):
    """A write that fails once it has made the image folder (a full disk)
    takes the folders it made back with the rest (an empty one was left)."""
    import importlib

    png_files = importlib.import_module(pkg.__name__ + ".png_files")
    H.reset()
    obj = H.textured_plane("Full")
    write_pngs = png_files.write_pngs

    def full_disk(files):
        raise OSError(28, "No space left on device")

    with scratch_folder("atlas_defrag_full_") as folder:
        png_files.write_pngs = full_disk
        try:
            message = _report_error(pkg, lambda: pkg.defragment(obj, storage="SAVE",
                                                                 image_dir=os.path.join(folder, "new", "maps")))
        finally:
            png_files.write_pngs = write_pngs
        assert "No space left" in message, message
        assert os.listdir(folder) == [], os.listdir(folder)


def obj_output_names_a_base_colour_behind_a_mix(pkg):
    """Blender's glTF importer puts a Mix node between the image and Base
    Color for vertex colours or a colour factor, and Blender's OBJ exporter
    then names no map: for an OBJ output the image is linked straight, with
    a warning."""
    import importlib

    batch = importlib.import_module(pkg.__name__ + ".batch")
    H.reset()
    obj = H.textured_plane("Mixed")
    tree = obj.material_slots[0].material.node_tree
    tex = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeTexImage")
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    mix = tree.nodes.new("ShaderNodeMixRGB")
    tree.links.new(tex.outputs["Color"], mix.inputs[1])
    tree.links.new(mix.outputs[0], bsdf.inputs["Base Color"])
    warnings = batch._base_colours_wired_straight([obj])
    assert bsdf.inputs["Base Color"].links[0].from_node == tex
    assert len(warnings) == 1 and "Mixed_mat" in warnings[0] and mix.name in warnings[0], warnings
    assert batch._base_colours_wired_straight([obj]) == []  # straight already
    reroute = tree.nodes.new("NodeReroute")
    tree.links.new(tex.outputs["Color"], reroute.inputs[0])
    tree.links.new(reroute.outputs[0], bsdf.inputs["Base Color"])
    assert batch._base_colours_wired_straight([obj]) == []  # the exporter follows reroutes: nothing to say


def default_uv_readers_keep_the_old_map(pkg):
    """The new map becomes active and render-active: whatever read the old
    ones without naming them keeps reading them by name. A second material's
    image node with nothing in its Vector input, a Texture Coordinate node's
    UV output through a Mapping node, a Displace modifier with no UV map
    named; and the old map keeps its pins. One undo step takes it all back."""
    H.reset()
    obj = H.textured_plane("Readers", uv_maps=2)
    me = obj.data
    me.uv_layers[1].name = "Scan"
    me.uv_layers.active = me.uv_layers["Scan"]
    me.uv_layers["UVMap"].active_render = True
    scan_mat = me.materials[0]
    label = scan_mat.copy()  # its image node reads the render-active map
    label.name = "Label"
    uv_node = scan_mat.node_tree.nodes.new("ShaderNodeUVMap")
    uv_node.uv_map = "Scan"
    scan_mat.node_tree.links.new(uv_node.outputs["UV"], H.image_nodes(scan_mat)[0].inputs["Vector"])
    tree = label.node_tree
    detail = tree.nodes.new("ShaderNodeTexImage")
    detail.image = H.image_nodes(label)[0].image
    coords, mapping = tree.nodes.new("ShaderNodeTexCoord"), tree.nodes.new("ShaderNodeMapping")
    tree.links.new(coords.outputs["UV"], mapping.inputs["Vector"])
    tree.links.new(mapping.outputs["Vector"], detail.inputs["Vector"])
    me.materials.append(label)
    me.polygons.foreach_set("material_index", np.arange(len(me.polygons), dtype=np.int32) % 2)
    displace = obj.modifiers.new("Displace", "DISPLACE")
    displace.texture_coords = "UV"
    flags = pkg.compat.uv_flags(me, "Scan")
    pins = next(iter(flags.values()))  # the pins, in either version
    pins[:3] = True
    pkg.compat.set_uv_flags(me, "Scan", flags)
    H.make_active(obj)
    before = H.object_state(obj.name)
    H.undo_push("before defragment")
    assert run_operator(pkg, undo=True, uv_map="Scan") == {"FINISHED"}
    assert me.uv_layers.active.name == "Scan_defrag" and me.uv_layers["Scan_defrag"].active_render
    assert H.vector_uv_map(H.image_nodes(label)[0]) == "UVMap"
    assert mapping.inputs["Vector"].links[0].from_node.bl_idname == "ShaderNodeUVMap"
    assert mapping.inputs["Vector"].links[0].from_node.uv_map == "UVMap"
    assert displace.uv_layer == "Scan"
    flags = pkg.compat.uv_flags(me, "Scan")
    assert np.array_equal(next(iter(flags.values())), pins), "the old map lost its pins"
    assert not next(iter(pkg.compat.uv_flags(me, "Scan_defrag").values())).any()
    H.undo()
    after_undo = H.object_state("Readers")  # undo made new Python objects of everything
    assert after_undo == before, _diff(before, after_undo)
    assert bpy.data.objects["Readers"].modifiers["Displace"].uv_layer == ""


def _image_group(name, image):
    """A node group holding one Image Texture node of image, Vector input
    empty, its colour the group's output."""
    group = bpy.data.node_groups.new(name, "ShaderNodeTree")
    if hasattr(group, "interface"):  # 4.0+
        group.interface.new_socket("Value", in_out="OUTPUT", socket_type="NodeSocketFloat")
    else:
        group.outputs.new("NodeSocketFloat", "Value")
    tex, out = group.nodes.new("ShaderNodeTexImage"), group.nodes.new("NodeGroupOutput")
    tex.image = image
    group.links.new(tex.outputs["Color"], out.inputs[0])
    return group


def _use_group(mat, group, socket):
    tree = mat.node_tree
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tree.links.new(node.outputs[0], bsdf.inputs[socket])


def images_in_node_groups_keep_the_old_map(pkg):
    """An image node inside a node group reads the render-active map too: it
    is pinned to the old map inside the group and named in a warning (the job
    does not rebuild it), unless another mesh draws the group through a map
    named otherwise, which the warning says. A group that reads no UV map,
    or one pinned already (by another object's run), is not named. With the
    base colour in a group the refusal says where the image is."""
    H.reset()
    obj, second, other = H.textured_plane("Grouped"), H.textured_plane("Second"), H.textured_plane("Other")
    image = H.image_nodes(obj.data.materials[0])[0].image
    pinned, shared = _image_group("Rough", image), _image_group("Shared", image)
    plain = bpy.data.node_groups.new("Plain", "ShaderNodeTree")
    _use_group(obj.data.materials[0], pinned, "Roughness")
    _use_group(second.data.materials[0], pinned, "Roughness")
    _use_group(obj.data.materials[0], shared, "Metallic")
    other.data.uv_layers[0].name = "Elsewhere"
    _use_group(other.data.materials[0], shared, "Metallic")
    for mat in (obj.data.materials[0], other.data.materials[0]):
        mat.node_tree.nodes.new("ShaderNodeGroup").node_tree = plain
    H.make_active(obj)
    report = pkg.defragment(obj)
    assert H.vector_uv_map(next(n for n in pinned.nodes if n.bl_idname == "ShaderNodeTexImage")) == "UVMap"
    assert not next(n for n in shared.nodes if n.bl_idname == "ShaderNodeTexImage").inputs["Vector"].is_linked
    assert any("'Grouped_tex' in node group 'Rough'" in w and "not rebuilt" in w for w in report["warnings"])
    assert any(w.startswith("Node group 'Shared' read the render-active UV map") for w in report["warnings"])
    assert not any("Plain" in w for w in report["warnings"]), report["warnings"]
    H.make_active(second)
    assert not any("Rough" in w for w in pkg.defragment(second)["warnings"])
    lone = H.textured_plane("OnlyInGroup")
    mat = lone.data.materials[0]
    _use_group(mat, _image_group("Base", H.image_nodes(mat)[0].image), "Base Color")
    mat.node_tree.nodes.remove(H.image_nodes(mat)[0])
    H.make_active(lone)
    try:
        pkg.defragment(lone)
    except pkg.DefragError as exc:
        assert "in node group 'Base'" in str(exc) and "ungroup" in str(exc), str(exc)
    else:
        raise AssertionError("a base colour only inside a group was taken")


def an_image_already_named_as_the_new_one_keeps_its_name(pkg):
    """A user's image named <image>_defrag stays that image; the new one is
    numbered (Blender 3.4 gave a renamed image the name, numbering the other)."""
    H.reset()
    obj = H.textured_plane("Named")
    theirs = bpy.data.images.new("Named_tex_defrag", 8, 8)
    pointer = theirs.as_pointer()
    H.make_active(obj)
    report = pkg.defragment(obj)
    assert bpy.data.images["Named_tex_defrag"].as_pointer() == pointer
    assert tuple(bpy.data.images["Named_tex_defrag"].size) == (8, 8)
    assert report["images"] == ["Named_tex_defrag.001"], report["images"]
    return report["images"]


def long_uv_map_names_fit_the_nodes(pkg):
    """A UV Map node holds 63 bytes of a map's name (4.x maps may be longer):
    the new map's name is cut to fit, and a render map longer than that is
    refused before anything changes."""
    H.reset()
    obj = H.textured_plane("Long")
    name = "texture_coordinates_from_the_photogrammetry_package_v2_uv0"  # 58 bytes: 65 with _defrag
    obj.data.uv_layers[0].name = name
    H.make_active(obj)
    r = pkg.defragment(obj)
    node = next(n for n in obj.material_slots[0].material.node_tree.nodes
                if n.bl_idname == "ShaderNodeUVMap" and n.uv_map.endswith("_defrag"))
    assert node.uv_map == r["uv_map"] == name[:56] + "_defrag", (node.uv_map, r["uv_map"])
    assert r["uv_map"] in obj.data.uv_layers
    if bpy.app.version < (4, 0, 0):
        return  # 3.x cuts map names at 63 bytes itself
    obj = H.textured_plane("Longer")
    obj.data.uv_layers[0].name = "x" * 70
    H.make_active(obj)
    before = H.object_state(obj.name)
    try:
        pkg.defragment(obj)
    except pkg.DefragError as exc:
        assert "longer than 63 bytes" in str(exc), exc
    else:
        raise AssertionError("a render map name of 70 bytes was not refused")
    assert H.object_state(obj.name) == before


SCENARIOS = {
    "an_image_reading_another_map_decides_the_default_map": an_image_reading_another_map_decides_the_default_map,
    "an_object_linked_slot_is_not_another_user": an_object_linked_slot_is_not_another_user,
    "the_base_colours_map_is_the_default_among_several": the_base_colours_map_is_the_default_among_several,
    "operator_tetra": lambda pkg: operator_on_model(pkg, "tetra"),
    "operator_smithsonian": lambda pkg: operator_on_model(pkg, "smithsonian"),
    "operator_meshroom": lambda pkg: operator_on_model(pkg, "meshroom"),
    "edit_mode_undo": edit_mode_undo,
    "python_entry": python_entry,
    "duplicate_materials_and_removal": duplicate_materials_and_removal,
    "save_beside_blend": save_beside_blend,
    "world_scale_density": world_scale_density,
    "cancel_leaves_nothing": cancel_leaves_nothing,
    "worker_thread_run": worker_thread_run,
    "write_identity_layout": write_identity_layout,
    "linked_duplicate_with_its_own_material_is_named": linked_duplicate_with_its_own_material_is_named,
    "material_index_past_the_slots_keeps_drawing_with_the_last":
        material_index_past_the_slots_keeps_drawing_with_the_last,
    "png_read_from_file": png_read_from_file,
    "fbx_round_trip_meshroom": lambda pkg: export_round_trip(pkg, "meshroom", "fbx"),
    "fbx_round_trip_smithsonian": lambda pkg: export_round_trip(pkg, "smithsonian", "fbx"),
    "obj_round_trip_meshroom": lambda pkg: export_round_trip(pkg, "meshroom", "obj"),
    "save_reopen": save_reopen,
    "several_objects": several_objects,
    "redo_asks_first": redo_asks_first,
    "several_objects_one_fails": several_objects_one_fails,
    "shared_material_one_at_a_time": shared_material_one_at_a_time,
    "quads_stay_whole": quads_stay_whole,
    "scan_quads_stay_whole": scan_quads_stay_whole,
    "one_atlas_for_all_selected": one_atlas_for_all_selected,
    "one_atlas_shared_material": one_atlas_shared_material,
    "source_uv_warning_names_rendered_nodes": source_uv_warning_names_rendered_nodes,
    "operator_takes_what_it_is_told": operator_takes_what_it_is_told,
    "image_settings_the_bake_cannot_follow_are_said": image_settings_the_bake_cannot_follow_are_said,
    "linear_float_images_keep_their_colour_space": linear_float_images_keep_their_colour_space,
    "obj_output_names_a_base_colour_behind_a_mix": obj_output_names_a_base_colour_behind_a_mix,
    "default_uv_readers_keep_the_old_map": default_uv_readers_keep_the_old_map,
    "long_uv_map_names_fit_the_nodes": long_uv_map_names_fit_the_nodes,
    "an_image_already_named_as_the_new_one_keeps_its_name": an_image_already_named_as_the_new_one_keeps_its_name,
    "material_shared_with_an_unselected_object": material_shared_with_an_unselected_object,
    "images_in_node_groups_keep_the_old_map": images_in_node_groups_keep_the_old_map,
    "premultiplied_byte_images_keep_their_colours": premultiplied_byte_images_keep_their_colours,
    "a_failed_save_takes_back_its_folders": a_failed_save_takes_back_its_folders,
}
for _case in ERRORS:
    SCENARIOS["error_" + _case] = (lambda c: (lambda pkg: error_case(pkg, c)))(_case)
