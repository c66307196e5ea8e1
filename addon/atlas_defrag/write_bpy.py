# SPDX-License-Identifier: MIT
"""Writes a job result into Blender: a new UV map, new images, rewired materials.

Called only after the native work succeeded. The source UV map and images are
never modified. If anything fails half-way, what was already done is rolled
back before the exception propagates.
"""

from __future__ import annotations

import itertools
import os
import re
import shutil
import tempfile
from dataclasses import dataclass, field
from typing import Callable, Dict, List, Optional, Tuple

import bpy
import numpy as np

from . import compat, made_folders, png_files, read_bpy
from .job import DefragError, JobResult, OutputImage, loop_uvs, with_channels
from .read_bpy import ReadResult, mesh_signature

SUFFIX = "_defrag"
UV_NODE_LABEL = "Atlas Defrag UV"
PIN_NODE_LABEL = "Atlas Defrag: original UV"


class _Journal:
    """Undo log of the changes made so far, replayed in reverse on failure."""

    def __init__(self):
        self._undo: List[Callable[[], None]] = []

    def add(self, fn: Callable[[], None]) -> None:
        self._undo.append(fn)

    def rollback(self) -> None:
        while self._undo:
            fn = self._undo.pop()
            try:
                fn()
            except Exception:  # best effort: keep undoing the rest
                pass


_IMAGE_EXT = re.compile(r"\.(png|jpe?g|tga|tiff?|exr|bmp|webp|hdr|j2c|jp2)(?=_defrag|$)", re.IGNORECASE)


def image_stem(name: str) -> str:
    """An image name without its file extension: 'photo.jpg' -> 'photo'."""
    return _IMAGE_EXT.sub("", name) or name


def _safe_file_stem(name: str) -> str:
    """File name for an image name: 'photo.jpg_defrag' -> 'photo_defrag'."""
    stem = image_stem(name)
    stem = re.sub(r"[^\w\-.]+", "_", stem).strip("._") or "image"
    return stem


def _numbered(stem: str, ext: str = ""):
    """stem + ext, then stem.001 + ext, stem.002 + ext, ...: how Blender numbers a name taken."""
    yield stem + ext
    for k in itertools.count(1):
        yield f"{stem}.{k:03d}{ext}"


def _unique_path(directory: str, stem: str, ext: str, taken: set) -> str:
    path = next(p for p in (os.path.join(directory, n) for n in _numbered(stem, ext))
                if p not in taken and not os.path.exists(p))
    taken.add(path)
    return path


def _set_look(img, out: OutputImage) -> None:
    """The source's colour space and alpha mode; but Blender hands out an
    8-bit premultiplied image's pixels with straight alpha, and so they were
    baked and written: such an output is tagged straight, or Blender would
    divide its colours by alpha a second time."""
    compat.set_colorspace(img, out.colorspace)
    try:
        img.alpha_mode = "STRAIGHT" if out.alpha_mode == "PREMUL" and not out.is_float else out.alpha_mode
    except (TypeError, ValueError):
        pass


def _new_float_image(out: OutputImage, name: str):
    """A float output as a Blender image (8-bit ones go through png_files),
    and the colour space its file takes once saved (_raw_file_tag): until
    then it is tagged Non-Color, so that Blender saves its values as they are
    (tagged so after the pixels are in, a generated image would be cleared)."""
    h, w = out.pixels.shape[:2]
    img = bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=True)
    _set_look(img, out)
    tag = _raw_file_tag(img)
    if tag:
        img.colorspace_settings.name = "Non-Color"
    img.pixels.foreach_set(np.ascontiguousarray(with_channels(out.pixels, 4), dtype=np.float32).reshape(-1))
    img.update()
    return img, tag


def _save_exr(img, path: str, tag: str) -> None:
    """Float buffers are written as they are only when channel packed:
    other alpha modes (un)premultiply on save and the values drift. tag:
    the colour space of a file written raw (_new_float_image), "" if none."""
    img.alpha_mode = "CHANNEL_PACKED"
    img.file_format = "OPEN_EXR"
    if hasattr(img, "use_half_precision"):
        img.use_half_precision = False
    img.filepath_raw = path
    img.save()
    img.source = "FILE"
    if tag:
        img.colorspace_settings.name = tag
    _point_at(img, path)


def _sixteen_bit_colour(out: OutputImage, sources: dict, in_unit_range: Dict[str, bool]) -> bool:
    """Whether a float output is an sRGB colour map that a 16-bit PNG holds:
    its source's values all in [0, 1], as a 16-bit PNG's or TIFF's are (up to
    the round-off of Blender's turning them linear), and its alpha, if any,
    straight (other modes keep OpenEXR, whose values Blender reads back
    as they were written). in_unit_range: that test per source, filled as
    sources are met (the pages of one source share it)."""
    source = sources.get(out.source)
    if not out.is_float or out.colorspace != "sRGB" or source is None:
        return False
    if out.pixels.shape[2] in (2, 4) and out.alpha_mode != "STRAIGHT":
        return False
    if out.source not in in_unit_range:
        pixels = source.pixels
        in_unit_range[out.source] = not pixels.size or (float(pixels.min()) >= -1e-4 and
                                                        float(pixels.max()) <= 1 + 1e-4)
    return in_unit_range[out.source]


def _sixteen_bit_srgb(pixels: np.ndarray) -> np.ndarray:
    """The 16-bit samples of a PNG holding an sRGB float map whose source lies
    in [0, 1] (a 16-bit PNG or TIFF), as Blender holds it (scene linear,
    colours premultiplied by alpha): colours divided by alpha, clipped to
    [0, 1] (where resampling overshot), then sRGB-encoded. Written as OpenEXR,
    such a map would hold sRGB values, which every other reader takes for linear."""
    if pixels.shape[2] not in (1, 3, 4):
        pixels = with_channels(pixels, 4)
    colour = np.clip(pixels, 0, 1, dtype=np.float32)
    if colour.shape[2] == 4:
        alpha = colour[:, :, 3:]
        np.divide(colour[:, :, :3], alpha, out=colour[:, :, :3], where=alpha > 0)
        np.minimum(colour[:, :, :3], 1, out=colour[:, :, :3])
    rgb = colour[:, :, :3]  # a view: colour itself but for alpha
    rgb[...] = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055)
    return np.rint(colour * 65535).astype(np.uint16)


def _raw_file_tag(img) -> str:
    """Blender saves an sRGB float image's buffer (scene linear) as sRGB
    values, and would save any other as sRGB too and tag it sRGB. "" for an
    sRGB image; else the colour space of its file written raw: its own for
    data and scene linear ones, scene linear for the rest."""
    settings = img.colorspace_settings
    if settings.name == "sRGB":
        return ""
    scene_linear = "Linear" if bpy.app.version < (4, 0, 0) else "Linear Rec.709"
    return settings.name if settings.is_data or settings.name == scene_linear else scene_linear


def _load_saved_png(out: OutputImage, name: str, path: str):
    """The image written by png_files at path, as a FILE image named name
    (name.001, ... where an image has that name: Blender 3.4 would give the
    name to the new image and rename the other)."""
    img = bpy.data.images.load(path, check_existing=False)
    img.name = _untaken(name, bpy.data.images, img)
    _set_look(img, out)
    _point_at(img, path)
    return img


def _untaken(name: str, ids, own) -> str:
    """name, or the first of name.001, name.002, ... that no ID in ids but own has."""
    return next(n for n in _numbered(name) if n not in ids or ids[n] == own)


def _point_at(img, path: str) -> None:
    """Relative to a saved .blend where it can be, so the folder can move."""
    if bpy.data.filepath:
        try:
            img.filepath = bpy.path.relpath(path)
        except ValueError:  # another drive
            img.filepath = path
    else:
        img.filepath = path


def _place_left_of(node, other, dx: float):
    other.location = (node.location[0] - dx, node.location[1])


def _relink(tree, from_socket, to_socket, journal: _Journal):
    """Links from_socket -> to_socket, recording the links it replaces."""
    old = [(lk.from_node.name, lk.from_socket.identifier) for lk in to_socket.links]
    for lk in list(to_socket.links):
        tree.links.remove(lk)
    new = tree.links.new(from_socket, to_socket)
    to_node_name, to_ident = to_socket.node.name, to_socket.identifier

    def undo():
        to_node = tree.nodes[to_node_name]
        sock = next(s for s in to_node.inputs if s.identifier == to_ident)
        for lk in list(sock.links):
            tree.links.remove(lk)
        for fn, fi in old:
            src = tree.nodes[fn]
            tree.links.new(next(s for s in src.outputs if s.identifier == fi), sock)
    journal.add(undo)
    return new


def _add_node(tree, idname, label, journal: _Journal):
    node = tree.nodes.new(idname)
    node.label = label
    name = node.name
    journal.add(lambda: tree.nodes.remove(tree.nodes[name]) if name in tree.nodes else None)
    return node


def _set_attr(obj, attr, value, journal: _Journal):
    old = getattr(obj, attr)
    setattr(obj, attr, value)
    journal.add(lambda: setattr(obj, attr, old))


def _rewire_material(mat, info, new_uv: str, page_images: Dict[str, object], journal: _Journal) -> None:
    tree = mat.node_tree
    uv_node = None
    for nm in info.maps:
        node = tree.nodes[nm.node]
        if uv_node is None:
            uv_node = _add_node(tree, "ShaderNodeUVMap", UV_NODE_LABEL, journal)
            uv_node.uv_map = new_uv
            _place_left_of(node, uv_node, 260.0)
        _set_attr(node, "image", page_images[nm.role], journal)
        _relink(tree, uv_node.outputs["UV"], node.inputs["Vector"], journal)
        for name in nm.normal_nodes:
            _set_attr(tree.nodes[name], "uv_map", new_uv, journal)


def _default_uv_readers(tree) -> list:
    """The nodes of a material's or a node group's tree (or None) that read
    the render-active UV map without naming it: image nodes with nothing in
    their Vector input, Texture Coordinate nodes whose UV output is used, UV
    Map and tangent Normal Map nodes with no map named."""
    def reads(node):
        kind = node.bl_idname
        if kind == "ShaderNodeTexImage":
            return node.image is not None and not node.inputs["Vector"].is_linked
        if kind == "ShaderNodeTexCoord":
            return node.outputs["UV"].is_linked
        named = kind == "ShaderNodeUVMap" or kind == "ShaderNodeNormalMap" and node.space == "TANGENT"
        return named and not node.uv_map
    return [node for node in tree.nodes if reads(node)] if tree is not None else []


def _pin_to_old_map(tree, readers: list, render_uv: str, journal: _Journal) -> None:
    """readers, the _default_uv_readers of tree, name the old map: the new
    map is render-active now."""
    pin = None

    def pinned(near):
        nonlocal pin
        if pin is None:
            pin = _add_node(tree, "ShaderNodeUVMap", PIN_NODE_LABEL, journal)
            pin.uv_map = render_uv
            _place_left_of(near, pin, 260.0)
        return pin.outputs["UV"]

    for node in readers:
        if node.bl_idname == "ShaderNodeTexImage":
            _relink(tree, pinned(node), node.inputs["Vector"], journal)
        elif node.bl_idname == "ShaderNodeTexCoord":
            for link in list(node.outputs["UV"].links):
                _relink(tree, pinned(node), link.to_socket, journal)
        else:
            _set_attr(node, "uv_map", render_uv, journal)


def _pin_default_uv_users(target: _Target, active_uv: Optional[str]) -> None:
    """What read the mesh's render-active or active UV map without naming it
    keeps reading the old one, now that the new map is both: the materials of
    every object drawing the mesh (see _pin_to_old_map) and the modifiers'
    empty UV map fields. A material that meshes with another render-active
    map also draw is left alone (pinning would change them) and named in a
    warning."""
    me, render_uv, journal = target.obj.data, target.read.render_uv, target.journal
    users = [o for o in bpy.data.objects if o.data == me]
    shared = []
    materials = list(dict.fromkeys(s.material for o in users for s in o.material_slots if s.material))
    for mat in materials:
        if _drawn_elsewhere_through_another_map(mat, me, render_uv):
            shared.append(f"material '{mat.name}'")
        else:
            tree = compat.node_tree(mat)
            _pin_to_old_map(tree, _default_uv_readers(tree), render_uv, journal)
    shared += _pin_node_groups(target, materials)
    for mod in (m for o in users for m in o.modifiers):
        for attr in ("uv_layer", "mask_tex_uv_layer"):
            if active_uv and getattr(mod, attr, None) == "":
                _set_attr(mod, attr, active_uv, journal)
    if shared:
        named = ", ".join(sorted(shared))
        target.warnings.append(f"{named[0].upper() + named[1:]} read the render-active UV map "
                               f"without naming it, and other meshes draw them through maps not named "
                               f"'{render_uv}': on this mesh they now read the new map (name the map in "
                               "their UV Map nodes to keep the old one)")


def _pin_node_groups(target: _Target, materials: list) -> List[str]:
    """_pin_to_old_map inside the node groups the materials use that read the
    render-active map without naming it, where every material using the
    group (and so every mesh drawing it) reads a map named like the old one;
    the others are returned, named, for the warning. A group linked from a
    library cannot change, and is said apart. The images pinned are not
    rebuilt: a warning names them."""
    me, render_uv = target.obj.data, target.read.render_uv
    groups = (g for mat in materials for g in read_bpy.node_groups(compat.node_tree(mat)))
    readers = {g: _default_uv_readers(g) for g in groups}
    reaching = {g: [] for g, nodes in readers.items() if nodes}
    if not reaching:
        return []
    for mat in bpy.data.materials:
        for g in read_bpy.node_groups(compat.node_tree(mat)):
            if g in reaching:
                reaching[g].append(mat)
    shared, linked, images = [], [], []
    for group, mats in reaching.items():
        if group.library is not None:
            linked.append(f"'{group.name}'")
        elif any(_drawn_elsewhere_through_another_map(m, me, render_uv) for m in mats):
            shared.append(f"node group '{group.name}'")
        else:
            images += [f"'{n.image.name}' in node group '{group.name}'" for n in readers[group]
                       if n.bl_idname == "ShaderNodeTexImage"]
            _pin_to_old_map(group, readers[group], render_uv, target.journal)
    if images:
        target.warnings.append(f"Image {', '.join(sorted(images))} not rebuilt: only Image Texture nodes at a "
                               "material's top level are (ungroup them, Ctrl+Alt+G, to have them rebuilt); "
                               f"they keep reading UV map '{render_uv}'")
    if linked:
        target.warnings.append(f"Node group(s) {', '.join(sorted(linked))}, linked from a library, read the "
                               "render-active UV map without naming it and cannot be changed: on this mesh they "
                               "now read the new map (make them local, then run again)")
    return shared


def _drawn_elsewhere_through_another_map(mat, me, render_uv: str) -> bool:
    """Whether an object drawing something other than me has mat in a slot
    and no render-active UV map named render_uv."""
    for o in bpy.data.objects:
        if o.data == me or not any(s.material == mat for s in getattr(o, "material_slots", [])):
            continue
        layers = getattr(o.data, "uv_layers", None)
        render = next((u.name for u in layers if u.active_render), None) if layers is not None else None
        if render != render_uv:
            return True
    return False


@dataclass
class SharedImages:
    """The new images of an atlas shared by several objects: the first
    object's write makes them, the others' writes rewire to them."""

    by_page_role: Dict[Tuple[int, str], object] = field(default_factory=dict)
    names: List[str] = field(default_factory=list)


def write(obj, read: ReadResult, result: JobResult, *, storage: str = "PACK",
          image_dir: Optional[str] = None, duplicate_materials: bool = False,
          new_map_first: bool = True, shared: Optional[SharedImages] = None) -> dict:
    """Applies the result to obj (which must be in Object mode). Returns what
    was created: {'uv_map', 'images', 'materials', 'warnings', ...}.

    new_map_first puts the new UV map at index 0 (the map that was there moves
    to the end): FBX readers and game engines texture through the first map.
    The originals the rewiring leaves without users get a fake user, so that
    saving the .blend keeps them. shared: the images of an atlas shared
    with objects written before (empty for the first, filled once it succeeded)."""
    if obj.mode != "OBJECT":
        raise DefragError("internal error: write() needs Object mode")
    if mesh_signature(obj) != read.signature:
        raise DefragError("The mesh or its materials changed while the atlas was being computed: "
                          "nothing was written")
    if storage not in ("PACK", "SAVE"):
        raise DefragError(f"storage must be 'PACK' or 'SAVE', not {storage!r}")
    image_dir = _image_dir(storage, image_dir)
    journal = _Journal()
    if storage == "SAVE":
        made = made_folders.missing(image_dir)
        os.makedirs(image_dir, exist_ok=True)
        journal.add(lambda: made_folders.remove_empty(made))
    try:
        return _write(obj, read, result, storage, image_dir, duplicate_materials, new_map_first, journal,
                      shared or SharedImages())
    except MemoryError as exc:
        journal.rollback()
        raise DefragError("Out of memory while writing the new images") from exc
    except BaseException:
        journal.rollback()
        raise
    finally:
        if storage == "PACK":  # the packed images hold the bytes now: runs would pile up pages here
            shutil.rmtree(image_dir, ignore_errors=True)


def _remove_file(path: str) -> None:
    try:
        os.remove(path)
    except FileNotFoundError:
        pass


def _image_dir(storage: str, image_dir: Optional[str]) -> str:
    """Where the new image files go. Packed images are written to a fresh
    folder in Blender's temporary one first (png_files encodes them in
    parallel), so their path ends in the image's name plus .png or .exr: the
    name the OBJ exporter writes as map_Kd."""
    if storage == "PACK":
        return tempfile.mkdtemp(prefix="atlas_defrag_", dir=bpy.app.tempdir or None)
    if not image_dir:
        if not bpy.data.filepath:
            raise DefragError("Save the .blend file first, or set Images to 'Pack in .blend'")
        image_dir = os.path.dirname(bpy.path.abspath(bpy.data.filepath))
    image_dir = bpy.path.abspath(image_dir)  # '//textures' is relative to the .blend
    if not os.path.isabs(image_dir):
        if not bpy.data.filepath:
            raise DefragError(f"Image folder '{image_dir}' is relative to an unsaved .blend: "
                              "save the file first, or give an absolute folder")
        image_dir = os.path.join(os.path.dirname(bpy.path.abspath(bpy.data.filepath)), image_dir)
    return image_dir


@dataclass
class _Target:
    """What every step of one write shares."""

    obj: object
    read: ReadResult
    result: JobResult
    journal: _Journal
    warnings: List[str] = field(default_factory=list)


def _write(obj, read, result, storage, image_dir, duplicate_materials, new_map_first, journal,
           shared: SharedImages) -> dict:
    if result.uvs.shape != (len(read.tri_loops), 3, 2) or result.face_page.shape != (len(read.tri_loops),):
        raise DefragError("internal error: the result does not match the mesh")
    target = _Target(obj, read, result, journal)
    if shared.by_page_role:
        page_role_image, created_images = shared.by_page_role, list(shared.names)
    else:
        page_role_image, created_images = _write_images(target, storage, image_dir)
    active_uv = obj.data.uv_layers.active.name if obj.data.uv_layers.active else None
    new_uv = _write_uv_map(target, new_map_first, active_uv)
    created_materials, rewired = _rewire_materials(target, new_uv, page_role_image, duplicate_materials)
    _pin_default_uv_users(target, active_uv)
    _keep_originals(target, duplicate_materials)
    obj.data.update()
    shared.by_page_role, shared.names = page_role_image, created_images
    return {"uv_map": new_uv, "new_map_first": new_map_first, "images": created_images,
            "materials": created_materials, "rewired_materials": rewired, "warnings": target.warnings}


def _write_images(target: _Target, storage: str, image_dir: Optional[str]):
    """One image per (new page, role): ({(page, role): image}, names created).
    8-bit images saved to files are encoded together (png_files)."""
    result, journal = target.result, target.journal
    group_pages: Dict[int, List[int]] = {}
    for q, g in enumerate(result.page_group.tolist()):
        group_pages.setdefault(g, []).append(q)
    taken: set = set()
    page_role_image: Dict[Tuple[int, str], object] = {}
    created_images: List[str] = []
    png_files_due = []  # (out, name, path)
    in_unit_range: Dict[str, bool] = {}

    def created(out, img):
        img_name = img.name
        journal.add(lambda n=img_name: bpy.data.images.remove(bpy.data.images[n])
                    if n in bpy.data.images else None)
        page_role_image[(out.page, out.role)] = img
        created_images.append(img_name)

    for out in result.images:
        pages = group_pages.get(int(result.page_group[out.page]), [out.page])
        k = pages.index(out.page) if out.page in pages else 0
        stem = image_stem(out.source)
        name = f"{stem}{SUFFIX}" if k == 0 else f"{stem}{SUFFIX}_{k + 1}"
        sixteen_bit = _sixteen_bit_colour(out, target.read.job.images, in_unit_range)
        samples = _sixteen_bit_srgb(out.pixels) if sixteen_bit else None
        ext = ".exr" if out.is_float and samples is None else ".png"
        path = _unique_path(image_dir, _safe_file_stem(name), ext, taken)
        journal.add(lambda p=path: _remove_file(p))  # a file is written only once its path is journalled
        if ext == ".png":
            png_files_due.append((out, name, path, out.pixels if samples is None else samples))
            continue
        img, tag = _new_float_image(out, name)
        created(out, img)
        _save_exr(img, path, tag)
    png_files.write_pngs((path, pixels) for _, _, path, pixels in png_files_due)
    for out, name, path, _ in png_files_due:
        created(out, _load_saved_png(out, name, path))
    if storage == "PACK":
        for img in page_role_image.values():
            _pack_beside_blend(img)
    return page_role_image, created_images


def _pack_beside_blend(img) -> None:
    """Packs the bytes of an image written to the temporary folder under the
    name of a file beside the .blend ('//') that neither exists nor names
    another image: unpacking it to its original place must not write into a
    folder that Blender deletes on exit, nor over another file. (The packed
    file keeps the path it was packed from, so the path comes first;
    filepath_raw changes it without reloading the image from there.)"""
    path = bpy.path.abspath(img.filepath)
    with open(path, "rb") as f:
        data = f.read()
    img.filepath_raw = _free_blend_path(os.path.basename(path), img)
    img.pack(data=data, data_len=len(data))


def _free_blend_path(file_name: str, own) -> str:
    """'//file_name', or '//stem.001.ext', ... : a path beside the .blend that
    no other image names and, for a saved .blend, no file takes."""
    named = {bpy.path.abspath(i.filepath) for i in bpy.data.images if i != own and i.filepath}

    def free(path: str) -> bool:
        absolute = bpy.path.abspath(path)
        return absolute not in named and not (bpy.data.filepath and os.path.lexists(absolute))

    return next(p for p in ("//" + n for n in _numbered(*os.path.splitext(file_name))) if free(p))


def _write_uv_map(target: _Target, first: bool, active_name: Optional[str]) -> str:
    """The new UV map, made active and render-active (active_name: the map
    active before, which an undo makes active again); returns its name."""
    me, read = target.obj.data, target.read
    per_loop, conflicts = loop_uvs(read.tri_loops, target.result.uvs, read.n_loops,
                                   lambda: compat.uv_coordinates(me.uv_layers[read.uv_map]))
    if conflicts:
        target.warnings.append(f"{conflicts} corners of quads or n-gons were split between charts: each keeps "
                               "one chart's UV, which distorts the texture on those polygons (triangulate the "
                               "mesh first, Ctrl+T, to avoid this)")
    render_name = read.render_uv
    layer = me.uv_layers.new(name=_node_sized(read.uv_map, SUFFIX), do_init=False)
    if layer is None:
        raise DefragError(f"Mesh '{me.name}' cannot take another UV map")
    new_uv = layer.name
    if len(new_uv.encode("utf-8")) > compat.NAME_BYTES:  # numbered past a taken name
        me.uv_layers.remove(layer)
        raise DefragError(f"Mesh '{me.name}' has UV maps of the new map's names up to {new_uv}: "
                          "remove or rename some")

    def undo_uv():
        m = bpy.data.meshes[read.mesh_name]
        if new_uv in m.uv_layers:
            m.uv_layers.remove(m.uv_layers[new_uv])
        if active_name in m.uv_layers:
            m.uv_layers.active = m.uv_layers[active_name]
        if render_name in m.uv_layers:
            m.uv_layers[render_name].active_render = True
    target.journal.add(undo_uv)
    if first and len(me.uv_layers) > 1:
        _move_to_front(me, new_uv, target.journal)
    layer = me.uv_layers[new_uv]  # adding a layer may move the others
    compat.set_uv_coordinates(layer, per_loop)
    me.uv_layers.active = layer
    layer.active_render = True
    return new_uv


def _node_sized(base: str, suffix: str) -> str:
    """base + suffix, base cut (at a character) so that the name fits a UV Map node."""
    while base and len((base + suffix).encode("utf-8")) > compat.NAME_BYTES:
        base = base[:-1]
    return base + suffix


def _move_to_front(me, name: str, journal: _Journal) -> None:
    """Swaps UV map name (the last one) with the first by name, data, pins
    and UV selection: Blender cannot reorder UV maps, and nodes refer to
    maps by name. Maps are looked up by name after each rename: 4.x may
    move what an older reference points at."""
    first_name = me.uv_layers[0].name
    first_data = compat.uv_coordinates(me.uv_layers[0])
    first_flags, new_flags = compat.uv_flags(me, first_name), compat.uv_flags(me, name)
    # Short and unused: Blender would cut a long name or rename a taken one.
    parking = next(p for p in (f"swap.{k}" for k in range(len(me.uv_layers) + 1)) if p not in me.uv_layers)
    _rename_in_turn(me, [(first_name, parking), (name, first_name), (parking, name)])
    compat.set_uv_coordinates(me.uv_layers[first_name], first_data)
    _swap_uv_flags(me, first_name, name, first_flags, new_flags)
    mesh_name = me.name

    def undo():
        m = bpy.data.meshes[mesh_name]
        compat.set_uv_coordinates(m.uv_layers[name], compat.uv_coordinates(m.uv_layers[first_name]))
        _rename_in_turn(m, [(name, parking), (first_name, name), (parking, first_name)])
        _swap_uv_flags(m, first_name, name, first_flags, new_flags)
    journal.add(undo)


def _swap_uv_flags(me, first_name: str, name: str, first_flags: dict, new_flags: dict) -> None:
    """Gives map first_name first_flags and map name new_flags, after a
    rename swapped the two maps' names: each map still holds the other's
    flags, and only the flags that differ are written (3.x writes flags
    corner by corner)."""
    differ = [flag for flag in first_flags if not np.array_equal(first_flags[flag], new_flags[flag])]
    compat.set_uv_flags(me, first_name, {flag: first_flags[flag] for flag in differ})
    compat.set_uv_flags(me, name, {flag: new_flags[flag] for flag in differ})


def _rename_in_turn(me, renames) -> None:
    for old, new in renames:
        me.uv_layers[old].name = new


def _used_elsewhere(mat, obj) -> bool:
    """Whether mat has users besides obj's mesh slots, obj's own object-linked
    slots and a fake user."""
    ours = sum(m == mat for m in obj.data.materials)
    ours += sum(s.link == "OBJECT" and s.material == mat for s in obj.material_slots)
    return mat.users > ours + mat.use_fake_user


def _rewire_materials(target: _Target, new_uv: str, page_role_image, duplicate_materials: bool):
    """One material per (source material, new page): the page with most faces
    keeps the slot, the others get new slots. Returns (created, rewired) names."""
    obj, read, result, journal = target.obj, target.read, target.result, target.journal
    me = obj.data
    poly_page = _polygon_pages(me, read, result)
    old_mat_index = np.empty(len(me.polygons), dtype=np.int32)
    me.polygons.foreach_get("material_index", old_mat_index)
    slot_count = len(obj.material_slots)
    clipped_index = np.clip(old_mat_index, 0, max(0, slot_count - 1))
    # An index past the last slot draws with that slot; once slots are
    # appended it would draw with a new page's material instead.
    new_mat_index = np.where(old_mat_index >= slot_count, clipped_index, old_mat_index)
    materials_before = len(me.materials)
    created_materials: List[str] = []
    rewired: List[str] = []
    shared_with_others: List[str] = []
    for info in read.materials:
        pages = _pages_by_use(info, read, result)
        if not pages:
            continue
        base = bpy.data.materials[info.name]
        if not duplicate_materials and _used_elsewhere(base, obj):
            shared_with_others.append(base.name)
        mats = _materials_for(base, len(pages), duplicate_materials, journal, created_materials)
        for k, (q, mat) in enumerate(zip(pages, mats)):
            images = {nm.role: page_role_image[(q, nm.role)] for nm in info.maps}
            _rewire_material(mat, info, new_uv, images, journal)
            rewired.append(mat.name)
            if k == 0:
                if duplicate_materials:
                    for s in info.slots:
                        _set_attr(obj.material_slots[s], "material", mat, journal)
            else:
                me.materials.append(mat)
                journal.add(lambda m=me: m.materials.pop(index=len(m.materials) - 1))
                polys = np.isin(clipped_index, info.slots) & (poly_page == q)
                new_mat_index[polys] = len(me.materials) - 1
    if len(me.materials) > materials_before and not np.array_equal(new_mat_index, old_mat_index):
        me.polygons.foreach_set("material_index", new_mat_index)
        journal.add(lambda m=me, a=old_mat_index: m.polygons.foreach_set("material_index", a))
    if shared_with_others:
        target.warnings.append("Material(s) also used by other objects were rewired: "
                               + ", ".join(sorted(set(shared_with_others)))
                               + " (use the duplicate-materials option to keep them)")
    return created_materials, rewired


def _keep_originals(target: _Target, duplicate_materials: bool) -> None:
    """A fake user on the source images (and, when duplicating, the source
    materials) so that a saved .blend keeps them once nothing uses them."""
    keep = [bpy.data.images[name] for name in target.read.job.images if name in bpy.data.images]
    if duplicate_materials:
        keep += [bpy.data.materials[info.name] for info in target.read.materials
                 if info.name in bpy.data.materials]
    for block in keep:
        _set_attr(block, "use_fake_user", True, target.journal)


def _polygon_pages(me, read: ReadResult, result: JobResult) -> np.ndarray:
    """(polygons,) the new page of each polygon's first triangle, -1 if none."""
    first_tri = np.full(len(me.polygons), -1, dtype=np.int64)
    # Loop triangles come polygon by polygon: a polygon's first one is where the index changes.
    polygons = read.tri_polygons
    starts = np.flatnonzero(np.r_[True, polygons[1:] != polygons[:-1]])
    first_tri[polygons[starts]] = starts
    return np.where(first_tri >= 0, result.face_page[np.maximum(first_tri, 0)], -1)


def _pages_by_use(info, read: ReadResult, result: JobResult) -> List[int]:
    """The new pages of a material's faces, the most used first."""
    if info.page < 0:
        return []
    faces = np.isin(read.slot_of_face, info.slots)
    pages = [int(q) for q in np.unique(result.face_page[faces]) if q >= 0]
    counts = [int(np.count_nonzero(result.face_page[faces] == q)) for q in pages]
    return [q for _, q in sorted(zip(counts, pages), key=lambda t: -t[0])]


def _materials_for(base, count: int, duplicate: bool, journal: _Journal, created: List[str]):
    """count materials: base itself first unless duplicating, then copies of
    it (made before any is rewired, from the untouched material)."""
    mats = []
    for k in range(count):
        if k == 0 and not duplicate:
            mats.append(base)
            continue
        mat = base.copy()
        mat.name = base.name + SUFFIX + ("" if k == 0 else f"_{k + 1}")
        mname = mat.name
        journal.add(lambda n=mname: bpy.data.materials.remove(bpy.data.materials[n])
                    if n in bpy.data.materials else None)
        created.append(mat.name)
        mats.append(mat)
    return mats
