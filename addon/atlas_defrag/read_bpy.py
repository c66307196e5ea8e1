# SPDX-License-Identifier: MIT
"""Reads an object into plain job data (bpy -> numpy). Never modifies anything."""

from __future__ import annotations

import io
import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import bpy
import numpy as np

from . import compat, image_headers, png_files
from .job import DefragError, ImageMap, JobInput, MeshData, SourcePage, reaches_past_page, role_sort_key

# Image sources whose pixels are one plain 2D image.
SUPPORTED_SOURCES = {"FILE", "GENERATED"}


@dataclass
class NodeMap:
    """An Image Texture node that will be rewired."""

    node: str  # node name in the material's tree
    role: str
    image: str  # bpy image name
    normal_nodes: List[str] = field(default_factory=list)  # tangent Normal Map nodes it feeds
    extension: str = "REPEAT"  # the node's: what it shows past the image's edges


@dataclass
class MaterialInfo:
    name: str  # material name
    slots: List[int]  # slot indices holding it
    page: int = -1  # source page, -1 when the material has no usable image map
    maps: List[NodeMap] = field(default_factory=list)


@dataclass
class ReadResult:
    job: JobInput
    mesh_name: str
    uv_map: str  # source UV map
    render_uv: str
    n_loops: int
    tri_loops: np.ndarray  # (F, 3) loop index per corner
    tri_polygons: np.ndarray  # (F,)
    slot_of_face: np.ndarray  # (F,) material slot per triangle (-1: none)
    materials: List[MaterialInfo]
    signature: tuple
    warnings: List[str] = field(default_factory=list)


def mesh_signature(obj, me=None) -> tuple:
    """Cheap fingerprint used to refuse writing onto a mesh edited meanwhile
    (me: the mesh data to count, a synced copy in Edit mode)."""
    me = me or obj.data
    return (obj.name, obj.data.name, len(me.vertices), len(me.loops), len(me.polygons),
            tuple(uv.name for uv in me.uv_layers), len(obj.material_slots))


def check_object(obj, uv_map: Optional[str] = None):
    """The checks that need no data: returns the source UV layer or raises."""
    if obj is None or getattr(obj, "type", None) != "MESH":
        raise DefragError("No active mesh: select a mesh object and make it active")
    me = obj.data
    _refuse_linked(obj)
    if len(me.polygons) == 0:
        raise DefragError(f"Mesh '{me.name}' has no faces (points or lines only): there is no texture to lay out")
    if len(me.uv_layers) == 0:
        raise DefragError(f"Mesh '{me.name}' has no UV map: unwrap it or import it with its UVs")
    if uv_map:
        layer = me.uv_layers.get(uv_map)
        if layer is None:
            raise DefragError(f"Mesh '{me.name}' has no UV map named '{uv_map}'")
    else:
        layer = _default_layer(obj)
    if len(me.uv_layers) >= compat.MAX_UV_MAPS:
        raise DefragError(
            f"Mesh '{me.name}' already has {len(me.uv_layers)} UV maps, the most Blender allows: "
            "remove one to make room for the new map")
    for name in {_render_uv_name(me), me.uv_layers.active.name if me.uv_layers.active else ""}:
        if len(name.encode("utf-8")) > compat.NAME_BYTES:
            raise DefragError(f"UV map '{name}' of mesh '{me.name}' has a name longer than {compat.NAME_BYTES} "
                              "bytes, which shader nodes and modifiers cannot hold: rename it")
    return layer


def _default_layer(obj):
    """The UV map a job reads when none is named: the active one, unless the
    image maps read none through it but read another (named by a UV Map
    node, or the render-active map): then the one the base colour reads,
    else the first such map in the mesh's order."""
    me = obj.data
    active = me.uv_layers.active or me.uv_layers[0]
    read = _maps_read_by_images(obj, _render_uv_name(me))
    if active.name in read:
        return active
    readers = [layer for layer in me.uv_layers if layer.name in read]
    return next((layer for layer in readers if "base_color" in read[layer.name]), readers[0] if readers else active)


def _maps_read_by_images(obj, render_uv: str) -> Dict[str, set]:
    """The UV maps that the Image Texture nodes of obj's materials read as
    plain UV lookups (flat projection) feeding a shader (named by a UV Map
    node, or the render-active map for nodes with no coordinates linked),
    each with the roles its images feed."""
    found: Dict[str, set] = {}
    for mat in {s.material for s in obj.material_slots if s.material is not None}:
        tree = compat.node_tree(mat)
        for node in tree.nodes if tree is not None else ():
            if node.bl_idname == "ShaderNodeTexImage" and _flat_lookup(node):
                kind, uv_name = _vector_source(node, render_uv)
                roles = _downstream_roles(node)[0]
                if kind != "other" and roles:
                    found.setdefault(uv_name, set()).update(roles)
    return found


def _flat_lookup(node) -> bool:
    """Whether an Image Texture node looks its image up flat, as the job can
    rebuild it: an image, flat projection, not muted."""
    return node.image is not None and node.projection == "FLAT" and not node.mute


def _refuse_linked(obj) -> None:
    """DefragError for an object, mesh or material linked from a library:
    Blender keeps no change to linked data (the new UV map would be all zero
    and vanish on reload). A library override of the object alone does not
    make its mesh local either."""
    blocks = [("Object", obj), ("Mesh", obj.data)] + \
        [("Material", s.material) for s in obj.material_slots if s.material is not None]
    for kind, block in blocks:
        if getattr(block, "library", None) is not None:
            raise DefragError(
                f"{kind} '{block.name}' is linked from the library '{block.library.filepath}' and cannot be "
                "changed: make it local first (Object > Relations > Make Local > "
                "Selected Objects, Data and Materials)")
def check_textures(obj, uv_map: Optional[str] = None) -> None:
    """check_object, and that some material has an image map on the UV map:
    the checks a dialog can make before it opens. Blender loads the images
    it would read itself, to see that they have pixels; plain PNGs are
    checked from their files' ends."""
    layer = check_object(obj, uv_map)
    warnings: List[str] = []
    materials = _analyse_slots(obj, layer.name, _render_uv_name(obj.data), warnings)
    if not any(info.maps for info in materials.values()):
        raise DefragError(_no_texture_message(obj, layer.name, warnings))


def _no_texture_message(obj, uv_name: str, warnings: List[str]) -> str:
    grouped = sorted({f"'{node.image.name}' in node group '{group.name}'"
                      for s in obj.material_slots for group, node in _grouped_images(s.material)})
    hint = (f" (image {', '.join(grouped)}: only Image Texture nodes at a material's top level are rebuilt; "
            "ungroup them, Ctrl+Alt+G, to have them rebuilt)" if grouped else "")
    read = set(_maps_read_by_images(obj, _render_uv_name(obj.data))) - {uv_name}
    elsewhere = [f"'{m}'" for m in sorted(read) if m in obj.data.uv_layers]
    missing = [f"'{m}'" for m in sorted(read) if m not in obj.data.uv_layers]
    if elsewhere:
        hint += f" (the image maps read UV map {', '.join(elsewhere)}: choose it as the UV map to defragment)"
    if missing:
        hint += f" (UV Map nodes name {', '.join(missing)}, which the mesh has no map of)"
    if warnings:  # it has image nodes, none the job can follow
        return f"No image texture this job can rebuild on '{obj.name}': " + "; ".join(warnings) + hint
    return (f"No image texture: no material of '{obj.name}' has an Image Texture node feeding "
            f"its Principled BSDF through UV map '{uv_name}'" + hint)


def node_groups(tree) -> list:
    """The node groups the nodes of tree (or None) use, and those these use,
    each once."""
    found, todo = {}, [tree] if tree is not None else []
    while todo:
        for node in todo.pop().nodes:
            group = node.node_tree if node.bl_idname == "ShaderNodeGroup" else None
            if group is not None and group not in found:
                found[group] = None
                todo.append(group)
    return list(found)


def _grouped_images(mat) -> List[tuple]:
    """(group, node) for every Image Texture node with an image inside the
    node groups mat uses: the job neither reads nor rewires them."""
    return [(group, node) for group in node_groups(compat.node_tree(mat)) for node in group.nodes
            if node.bl_idname == "ShaderNodeTexImage" and node.image is not None]


def _render_uv_name(me) -> str:
    for uv in me.uv_layers:
        if uv.active_render:
            return uv.name
    return me.uv_layers[0].name


def _follow_reroutes_back(link):
    while link is not None and link.from_node.bl_idname == "NodeReroute":
        inp = link.from_node.inputs[0]
        link = inp.links[0] if inp.is_linked else None
    return link


def _vector_source(node, render_uv: str) -> Tuple[str, Optional[str]]:
    """How an Image Texture node gets its coordinates.

    Returns (kind, uv_name): kind 'implicit' (unlinked: render UV map),
    'uvnode' (UV Map node), 'texcoord' (Texture Coordinate UV output), 'wrap'
    (a UV map through glTF wrap emulation) or 'other' (a transform or other
    coordinates: not a plain UV lookup).
    """
    sock = node.inputs.get("Vector")
    if sock is None or not sock.is_linked:
        return "implicit", render_uv
    link = _follow_reroutes_back(sock.links[0])
    if link is None:
        return "implicit", render_uv
    src = link.from_node
    if src.bl_idname == "ShaderNodeUVMap":
        return "uvnode", src.uv_map or render_uv
    if src.bl_idname == "ShaderNodeTexCoord" and link.from_socket.identifier == "UV":
        return "texcoord", render_uv
    uv = _wrap_emulation_source(link, render_uv)
    if uv is not None:
        return "wrap", uv
    return "other", None


# Nodes the glTF importer puts between a UV map and an image to emulate
# mirrored-repeat wrapping: the identity for UVs inside [0, 1], which is where
# the new layout puts every chart.
_WRAP_NODES = {"ShaderNodeSeparateXYZ", "ShaderNodeCombineXYZ", "NodeReroute"}
_WRAP_MATH = {"PINGPONG", "WRAP", "FRACT"}


def _wrap_emulation_source(link, render_uv: str) -> Optional[str]:
    """The UV map read through a wrap-emulation chain, or None if the chain
    does anything else (a Mapping node, other maths, other coordinates)."""
    found = set()
    stack = [link]
    seen = set()
    while stack:
        lk = stack.pop()
        node = lk.from_node
        if node.name in seen:
            continue
        seen.add(node.name)
        if node.bl_idname == "ShaderNodeUVMap":
            found.add(node.uv_map or render_uv)
            continue
        if node.bl_idname == "ShaderNodeTexCoord" and lk.from_socket.identifier == "UV":
            found.add(render_uv)
            continue
        if node.bl_idname == "ShaderNodeMath" and node.operation in _WRAP_MATH:
            pass
        elif node.bl_idname not in _WRAP_NODES:
            return None
        for inp in node.inputs:
            if inp.is_linked:
                stack.extend(inp.links)
            elif node.bl_idname == "ShaderNodeCombineXYZ" and inp.identifier != "Z":
                return None  # a constant coordinate: not a UV lookup
    return found.pop() if len(found) == 1 else None


def _downstream_roles(node) -> Tuple[List[str], List[str]]:
    """Roles an Image Texture node feeds: Principled BSDF inputs (through any
    converter nodes), the glTF group's Occlusion, or 'other' for any other
    shader. Also the names of the tangent-space Normal Map nodes on the way."""
    roles = set()
    normal_nodes: List[str] = []
    seen = set()
    stack = [(out, False, False) for out in node.outputs if out.is_linked]
    while stack:
        sock, via_normal, via_bump = stack.pop()
        for link in sock.links:
            if getattr(link, "is_muted", False) or not link.is_valid:
                continue
            to_node, to_sock = link.to_node, link.to_socket
            key = (to_node.name, to_sock.identifier, via_normal, via_bump)
            if key in seen:
                continue
            seen.add(key)
            idname = to_node.bl_idname
            if idname == "ShaderNodeBsdfPrincipled":
                role = compat.input_role(to_sock.name)
                if via_bump and role in ("normal", "coat_normal"):
                    role = "bump"
                roles.add(role)
                continue
            if compat.is_gltf_output_group(to_node):
                roles.add("occlusion" if to_sock.name.lower() == "occlusion" else
                          compat.input_role(to_sock.name))
                continue
            nxt_normal, nxt_bump = via_normal, via_bump
            if idname == "ShaderNodeNormalMap":
                if to_node.space == "TANGENT":
                    nxt_normal = True
                    if to_node.name not in normal_nodes:
                        normal_nodes.append(to_node.name)
            elif idname in ("ShaderNodeBump", "ShaderNodeDisplacement"):
                nxt_bump = True
            if to_node.type == "OUTPUT_MATERIAL" or any(o.type == "SHADER" for o in to_node.outputs):
                roles.add("other")
                continue
            for out in to_node.outputs:
                if out.is_linked:
                    stack.append((out, nxt_normal, nxt_bump))
    ordered = sorted(roles, key=role_sort_key)
    return ordered, normal_nodes


def _check_image(img, material_name: str):
    """None when the image can be read; a warning string when it has no pixels;
    raises DefragError when it can never be supported. A plain PNG is checked
    from its file's header, without Blender loading it."""
    if img.source == "TILED":
        raise DefragError(
            f"Image '{img.name}' in material '{material_name}' uses UDIM tiles: "
            "tiled images are not supported")
    if img.source not in SUPPORTED_SOURCES:
        raise DefragError(
            f"Image '{img.name}' in material '{material_name}' is a {img.source.lower()} "
            "image: only single still images are supported")
    if bpy.data.images.get(img.name) is not img:  # the job finds its images by name
        return (f"Image '{img.name}' in material '{material_name}' comes from the library "
                f"'{img.library.name if img.library else ''}' and this file has an image of that name: "
                "skipped (rename one of them)")
    if _plain_png(img):
        return None
    problem = _size_problem(img, material_name)
    if problem:
        return problem
    w, h = img.size
    if w <= 0 or h <= 0 or not _loads(img):
        return f"Image '{img.name}' in material '{material_name}' has no pixels (missing file?): skipped"
    return None


def _size_problem(img, material_name: str) -> Optional[str]:
    """Raises DefragError when img claims more pixels than bpy can hand out,
    than its file can hold, or than this machine's memory holds while they
    are read (image_headers.size_problem); a warning when its file has no
    header image_headers reads (damaged, or no image Blender reads). An image
    Blender has not loaded is judged by its file's header, before Blender
    decodes it (asking for img.size would). A missing file is left to Blender."""
    where = f"Image '{img.name}' in material '{material_name}'"
    try:
        claim, file_bytes = _claimed_size(img)
    except OSError:
        return None
    if claim is None:
        return f"{where} is damaged (cut short?) or no image file Blender reads: skipped"
    problem = image_headers.size_problem(claim, file_bytes)
    if problem:
        raise DefragError(f"{where} claims {problem}; scale it down or repair it first")
    return None


def _claimed_size(img) -> Tuple[Optional[image_headers.Claim], Optional[int]]:
    """(img's size without decoding it, its file's bytes): Blender's size
    (and None) when it holds the pixels or generates them, else its file's
    header (packed or on disk; None when image_headers cannot read it).
    OSError when there is no file to read."""
    if img.source == "GENERATED":
        return image_headers.Claim(img.generated_width, img.generated_height, bool(img.use_generated_float)), None
    if img.has_data:
        return image_headers.Claim(int(img.size[0]), int(img.size[1]), bool(img.is_float)), None
    if img.packed_file is not None:
        data = img.packed_file.data
        return _sound_claim(io.BytesIO(data), img.filepath), len(data)
    path = bpy.path.abspath(img.filepath, library=img.library)
    if not os.path.exists(path):
        raise FileNotFoundError(path)
    if not os.path.isfile(path):  # a FIFO or a device: Blender would wait on it, or read it without end
        return None, None
    with open(path, "rb") as f:
        return _sound_claim(f, img.filepath), os.fstat(f.fileno()).st_size


def _sound_claim(f, file_name: str) -> Optional[image_headers.Claim]:
    """The size f's header claims; None when it has none image_headers reads, or f is cut short."""
    claim = image_headers.claimed_size(f, file_name)
    return None if claim is None or image_headers.cut_short(f) else claim


def _loads(img) -> bool:
    return _pixel_count(img) > 0


def _pixel_count(img) -> int:
    """Values Blender holds for img (loading it), 0 when it cannot load it."""
    try:
        return len(img.pixels)
    except Exception:
        return 0


def _file_bytes(img) -> Optional[bytes]:
    """The image file's bytes, packed or on disk; None when there is no file to read."""
    if img.packed_file is not None:
        return img.packed_file.data
    try:
        with open(bpy.path.abspath(img.filepath, library=img.library), "rb") as f:
            return f.read()
    except (OSError, ValueError):
        return None


def _file_ends(img, head: int, tail: int) -> Optional[Tuple[bytes, bytes]]:
    """The first `head` and the last `tail` bytes of the image file, packed
    or on disk, without reading the rest from disk; None when there is no
    file to read."""
    if img.packed_file is not None:
        data = img.packed_file.data
        return data[:head], data[-tail:]
    try:
        return png_files.file_ends(bpy.path.abspath(img.filepath, library=img.library), head, tail)
    except (OSError, ValueError):
        return None


# Alpha modes under which Blender keeps an RGBA PNG's alpha as the file has
# it; with the others it premultiplies the colours or sets alpha opaque.
_FILE_ALPHA_MODES = {"STRAIGHT", "CHANNEL_PACKED"}


def _plain_png_size(img) -> Optional[Tuple[int, int, int]]:
    """(width, height, channels) from the header when img is a whole 8-bit
    RGB or RGBA PNG file that Blender has not loaded, and whose bytes
    png_files.decode_png turns into the pixels Blender would give (checked in
    3.4, 4.5 and 5.0); None otherwise. A loaded image may have been edited,
    or its file changed since: Blender's pixels are then the truth. A file
    cut short is left to Blender, which skips it with a warning. Loads
    nothing: asking Blender for an image's size or buffer type decodes the
    whole file."""
    if img.source != "FILE" or img.has_data:
        return None
    ends = _file_ends(img, png_files.HEADER_BYTES, png_files.TAIL_BYTES)
    size = png_files.plain_png_size(ends[0]) if ends is not None else None
    plain = (size is not None and png_files.ends_whole(ends[1])
             and (size[2] == 3 or img.alpha_mode in _FILE_ALPHA_MODES))
    return size if plain else None


def _plain_png(img) -> bool:
    """Whether img is a plain PNG (see _plain_png_size)."""
    return _plain_png_size(img) is not None


def _is_float(img) -> bool:
    """img.is_float without loading a plain PNG (the property decodes the file)."""
    return False if _plain_png(img) else bool(img.is_float)


def analyse_material(mat, uv_map: str, render_uv: str, warnings: List[str]) -> List[NodeMap]:
    """Image maps of one material that use uv_map. (What reads the render UV
    map without naming it is pinned to it when the result is written.)"""
    maps: List[NodeMap] = []
    tree = compat.node_tree(mat)
    if tree is None:
        return maps
    for node in tree.nodes:
        if node.bl_idname != "ShaderNodeTexImage":
            continue
        kind, uv_name = _vector_source(node, render_uv)
        img = node.image
        roles, normal_nodes = _downstream_roles(node)
        usable = _flat_lookup(node) and roles and uv_name == uv_map and kind != "other"
        if usable:
            problem = _check_image(img, mat.name)
            if problem:
                warnings.append(problem)
                usable = False
        if usable:
            maps.append(NodeMap(node=node.name, role="+".join(roles), image=img.name,
                                normal_nodes=normal_nodes, extension=node.extension))
        elif img is not None and kind == "other" and roles and node.projection == "FLAT":
            warnings.append(f"Image '{img.name}' in material '{mat.name}' is read through a "
                            "coordinate transform: left unchanged")
        elif _flat_lookup(node) and roles and uv_name != uv_map:
            warnings.append(f"Image '{img.name}' in material '{mat.name}' reads UV map '{uv_name}', not "
                            f"'{uv_map}': left unchanged, reading '{uv_name}'")
    return maps


def read_pixels(img) -> np.ndarray:
    """(H, W, C) row 0 = bottom; uint8 for byte images, float32 for float
    ones; C is the file's channels for an 8-bit grey (1) or RGB (3) file
    whose pixels Blender has not changed, else Blender's (4), as decode_png
    gives them.

    bpy hands out pixels as floats only; a byte image's values are b / 255,
    which the native module turns back into b exactly, on every core."""
    from . import _native

    w, h = img.size
    c = img.channels
    n = w * h * c
    count = _pixel_count(img)
    if n <= 0 or count == 0:
        raise DefragError(f"Image '{img.name}' has no pixels (missing or unreadable file?)")
    if count != n:
        raise DefragError(f"Image '{img.name}' has an unexpected pixel count")
    try:
        buf = np.empty(n, dtype=np.float32)
        img.pixels.foreach_get(buf)
        buf = buf.reshape(h, w, c)
        if img.is_float:
            return buf
        # Blender fills a grey file's G and B with its grey and an RGB file's
        # alpha with 255. The depth says which file it was, and the pixels
        # must bear it out (an edited image, or a TGA whose depth is that of
        # its colour map, keeps all four).
        return _native.bytes_from_unit_floats(buf, kept={8: 1, 24: 3}.get(img.depth, c))
    except MemoryError as exc:
        raise DefragError(f"Out of memory reading image '{img.name}' ({w}x{h})") from exc


def read(obj, uv_map: Optional[str] = None) -> ReadResult:
    """Collects everything the job needs. Raises DefragError with the reason."""
    layer = check_object(obj, uv_map)
    if obj.mode != "EDIT":
        return _read(obj, obj.data, layer.name)
    # In Edit mode the mesh arrays are stale and 4.x hides the UV data: read a
    # synced copy (removed again; the object is not touched).
    obj.update_from_editmode()
    copy = obj.data.copy()
    try:
        return _read(obj, copy, layer.name)
    finally:
        bpy.data.meshes.remove(copy)


@dataclass
class _Geometry:
    """The loop triangles of a mesh and their UVs on the source map."""

    positions: np.ndarray  # (V, 3) float64, world space
    triangles: np.ndarray  # (F, 3) int32 vertex per corner
    tri_loops: np.ndarray  # (F, 3) int32 loop per corner
    tri_polygons: np.ndarray  # (F,) int32
    tri_material: np.ndarray  # (F,) int32 material index
    uvs: np.ndarray  # (F, 3, 2) float64
    n_loops: int


def _read(obj, me, uv_name: str) -> ReadResult:
    render_uv = _render_uv_name(me)
    warnings: List[str] = []
    geo = _read_geometry(obj, me, me.uv_layers[uv_name])
    _refuse_non_finite(obj, uv_name, geo)
    warnings += _rounded_by_single_precision(obj, geo)
    materials = _analyse_slots(obj, uv_name, render_uv, warnings)
    n_slots = len(obj.material_slots)
    pages = _source_pages(materials, _used_slots(geo.tri_material, n_slots))
    slot_of_face, face_page = _face_pages(materials, geo.tri_material, n_slots)
    if not pages or not np.any(face_page >= 0):
        raise DefragError(_no_texture_message(obj, uv_name, warnings))
    warnings += _extended_past_edges(materials.values(), geo.uvs, slot_of_face)
    job = JobInput(
        mesh=MeshData(positions=geo.positions, triangles=geo.triangles, uvs=geo.uvs,
                      face_page=face_page.astype(np.int32),
                      polygons=geo.tri_polygons.astype(np.int32) if len(me.polygons) < len(geo.triangles) else None),
        pages=pages, images=_read_images(pages))
    return ReadResult(
        job=job, mesh_name=obj.data.name, uv_map=uv_name, render_uv=render_uv, n_loops=geo.n_loops,
        tri_loops=geo.tri_loops, tri_polygons=geo.tri_polygons, slot_of_face=slot_of_face.astype(np.int32),
        materials=list(materials.values()), signature=mesh_signature(obj, me), warnings=warnings)


def _refuse_non_finite(obj, uv_name: str, geo: _Geometry) -> None:
    """NaN or inf on the UV map or in the positions, named by what Edit mode
    shows (faces and vertices by index), not by the job's arrays."""
    bad_faces = np.unique(geo.tri_polygons[~np.isfinite(geo.uvs).all(axis=(1, 2))])
    if len(bad_faces):
        raise DefragError(f"UV map '{uv_name}' of '{obj.name}' has coordinates that are not numbers (NaN or inf) "
                          f"on {len(bad_faces)} face(s), face {bad_faces[0]} first: unwrap those faces again")
    bad_vertices = np.flatnonzero(~np.isfinite(geo.positions).all(axis=1))
    if len(bad_vertices):
        raise DefragError(f"'{obj.name}' has {len(bad_vertices)} vertex(es) whose position is not a number "
                          f"(NaN or inf) in world space, vertex {bad_vertices[0]} first: fix or delete them")


def _rounded_by_single_precision(obj, geo: _Geometry) -> List[str]:
    """A warning when the mesh lies so far from its origin that Blender's
    single-precision coordinates step by more than a hundredth of its median
    edge (a scan in map coordinates, UTM northings near 4e6 m): the import
    has rounded the shape already, and the result keeps it so. Each
    triangle's first edge stands for the edges."""
    t = geo.triangles
    edge = float(np.median(np.linalg.norm(geo.positions[t[:, 0]] - geo.positions[t[:, 1]], axis=1)))
    far = float(np.abs(geo.positions).max())
    step = far * 2.0 ** -23  # a float32's spacing there
    if step <= 0.01 * edge:
        return []
    return [f"{obj.name}: positions reach {far:.6g} from the origin, where Blender's single precision steps by "
            f"{step:.3g}, over a hundredth of the median edge ({edge:.3g}): the import rounded the shape; "
            "move the scan near the origin first"]


def _read_geometry(obj, me, layer) -> _Geometry:
    compat.calc_loop_triangles(me)
    n_tris = len(me.loop_triangles)
    if n_tris == 0:
        raise DefragError(f"Mesh '{obj.data.name}' has no faces")
    positions = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", positions)
    tri = {}
    for attr in ("vertices", "loops"):
        tri[attr] = np.empty(n_tris * 3, dtype=np.int32)
        me.loop_triangles.foreach_get(attr, tri[attr])
    for attr in ("polygon_index", "material_index"):
        tri[attr] = np.empty(n_tris, dtype=np.int32)
        me.loop_triangles.foreach_get(attr, tri[attr])
    n_loops = len(me.loops)
    loop_uv = compat.uv_coordinates(layer)
    tri_loops = tri["loops"].reshape(n_tris, 3)
    return _Geometry(positions=_scene_sized(obj, positions.reshape(-1, 3).astype(np.float64)),
                     triangles=tri["vertices"].reshape(n_tris, 3), tri_loops=tri_loops,
                     tri_polygons=tri["polygon_index"], tri_material=tri["material_index"],
                     uvs=loop_uv.reshape(n_loops, 2)[tri_loops].astype(np.float64), n_loops=n_loops)


def _scene_sized(obj, positions: np.ndarray) -> np.ndarray:
    """(V, 3) positions at the size the scene shows them (object and parent
    scales): texels_per_unit counts per unit of that surface, and the objects
    of a shared atlas agree on their sizes. A rotation is left out (no stage
    depends on it, and it would only add round-off), and so is a transform
    that flattens the object (the mesh's own shape is the one to keep)."""
    linear = np.array(obj.matrix_world.to_3x3(), dtype=np.float64)
    scales = np.linalg.norm(linear, axis=0)
    if not np.all(scales > 0) or abs(np.linalg.det(linear)) < 1e-12 * np.prod(scales):
        return positions
    gram = linear.T @ linear / scales.max() ** 2
    if np.allclose(scales, scales[0], rtol=1e-6) and np.allclose(gram, np.eye(3), atol=1e-6):
        scale = float(scales.mean())  # a uniform scale times a rotation
        return positions if abs(scale - 1.0) < 1e-6 else positions * scale
    return positions @ linear.T


def _analyse_slots(obj, uv_name: str, render_uv: str, warnings: List[str]) -> Dict[str, MaterialInfo]:
    """Every material in obj's slots, analysed once, with the slots holding it."""
    materials: Dict[str, MaterialInfo] = {}
    for i, slot in enumerate(obj.material_slots):
        mat = slot.material
        if mat is None:
            continue
        if mat.name in materials:
            materials[mat.name].slots.append(i)
            continue
        materials[mat.name] = MaterialInfo(name=mat.name, slots=[i],
                                           maps=analyse_material(mat, uv_name, render_uv, warnings))
    return materials


def _used_slots(tri_material: np.ndarray, n_slots: int) -> set:
    """Slots that faces actually use (out-of-range indices use the last slot)."""
    if not n_slots:
        return set()
    return set(np.unique(np.clip(tri_material, 0, n_slots - 1)).tolist())


def _source_pages(materials: Dict[str, MaterialInfo], used_slots: set) -> List[SourcePage]:
    """One page per distinct set of image maps; sets info.page. Pages whose
    roles, colour spaces and buffer types agree form one group."""
    pages: List[SourcePage] = []
    page_index: Dict[tuple, int] = {}
    group_index: Dict[tuple, int] = {}
    for info in materials.values():
        if not info.maps or not used_slots.intersection(info.slots):
            continue
        page_key = _page_key(info)
        if page_key not in page_index:
            gkey = tuple((role, bpy.data.images[image_name].colorspace_settings.name,
                          _is_float(bpy.data.images[image_name]))
                         for role, image_name, _ in page_key)
            group_index.setdefault(gkey, len(group_index))
            page_index[page_key] = len(pages)
            pages.append(SourcePage(
                maps=[ImageMap(role=r, image=n, normal_map=t) for r, n, t in page_key],
                group=group_index[gkey]))
        info.page = page_index[page_key]
    return pages


def _page_key(info: MaterialInfo) -> tuple:
    """(role, image, normal map) of each map, in role order. One image per
    role: a second, different image in the same role (e.g. two base colours
    mixed) becomes a role of its own ('base_color#2'); renames nm.role."""
    role_image: Dict[str, str] = {}
    for nm in info.maps:
        role, k = nm.role, 1
        while role in role_image and role_image[role] != nm.image:
            k += 1
            role = f"{nm.role}#{k}"
        nm.role = role
        role_image[role] = nm.image
    by_role = {nm.role: nm for nm in info.maps}
    return tuple(sorted(((nm.role, nm.image, bool(nm.normal_nodes)) for nm in by_role.values()),
                        key=lambda t: role_sort_key(t[0])))


def _extended_past_edges(materials, uvs: np.ndarray, slot_of_face: np.ndarray) -> List[str]:
    """A warning for each image whose node extends, clips or mirrors it
    (glTF's clamp-to-edge imports as Extend) where its faces' UVs leave the
    page: the bake repeats every image, so the new texture shows there what
    Repeat would."""
    out = []
    for info in materials:
        odd = {m.image: m.extension for m in info.maps if m.extension != "REPEAT"}
        if not odd:
            continue
        if reaches_past_page(uvs[np.isin(slot_of_face, info.slots)]):
            out += [f"Image '{image}' in material '{info.name}' is set to {extension.title()} and faces reach "
                    "past its edges: the new texture repeats it there, as Repeat would"
                    for image, extension in odd.items()]
    return out


def _face_pages(materials: Dict[str, MaterialInfo], tri_material: np.ndarray, n_slots: int):
    """(slot of each face, source page of each face), -1 where there is none."""
    n_tris = len(tri_material)
    if not n_slots:
        none = np.full(n_tris, -1, dtype=np.int32)
        return none, none.copy()
    slot_page = np.full(n_slots, -1, dtype=np.int32)
    for info in materials.values():
        for s in info.slots:
            slot_page[s] = info.page
    slot_of_face = np.clip(tri_material, 0, n_slots - 1)
    return slot_of_face, slot_page[slot_of_face]


class PendingImage:
    """A job.ImageData whose pixels come later, so that the layout (which
    needs only sizes) can run on a worker thread meanwhile: a plain PNG is
    decoded on a thread of its own from the start; Blender reads the others
    when the main thread calls fetch(). The main thread asking for the pixels
    fetches them itself; another thread waits for fetch(), so whoever hands
    the job to a worker calls fetch_pixels on the main thread (api.prepare
    does unless told not to)."""

    def __init__(self, img, plain_size: Optional[Tuple[int, int, int]] = None, decoding: Optional[Future] = None):
        """plain_size: _plain_png_size(img), known already; decoding: the
        pixels of a plain PNG being decoded."""
        self.name = img.name
        self.colorspace = img.colorspace_settings.name
        # Asked of Blender only when it holds the image anyway.
        self.is_float = False if plain_size else bool(img.is_float)
        self.alpha_mode = img.alpha_mode
        self.size = plain_size[:2] if plain_size else (int(img.size[0]), int(img.size[1]))
        self._decoding = decoding
        self._done = threading.Event()
        self._pixels: Optional[np.ndarray] = None
        self._error: Optional[BaseException] = None

    def fetch(self) -> None:
        """Reads the pixels (main thread only). An error is kept for whoever
        asks for them."""
        if self._done.is_set():
            return
        try:
            decoded = self._decoded()
            self._pixels = decoded if decoded is not None else read_pixels(bpy.data.images[self.name])
        except BaseException as exc:  # handed to the thread that asks for the pixels
            self._error = exc
        finally:
            self._done.set()

    def _decoded(self) -> Optional[np.ndarray]:
        try:
            return self._decoding.result() if self._decoding is not None else None
        except MemoryError as exc:
            raise DefragError(f"Out of memory reading image '{self.name}'") from exc

    @property
    def pixels(self) -> np.ndarray:
        if threading.current_thread() is threading.main_thread():
            self.fetch()
        self._done.wait()
        if self._error is not None:
            raise self._error
        return self._pixels


def _read_images(pages: List[SourcePage]) -> Dict[str, PendingImage]:
    """Every image of the pages, its pixels pending (PendingImage): plain
    PNGs start decoding from their files at once, side by side (the native
    inflate and row filters release the GIL)."""
    names = list(dict.fromkeys(m.image for page in pages for m in page.maps))
    sizes = {n: _plain_png_size(bpy.data.images[n]) for n in names}
    plain = {n: size for n, size in sizes.items() if size}
    pool = ThreadPoolExecutor(max_workers=max(1, min(len(plain), os.cpu_count() or 1)))
    try:
        decoding = {n: pool.submit(png_files.decode_png_or_none, _file_bytes(bpy.data.images[n])) for n in plain}
        return {n: PendingImage(bpy.data.images[n], plain.get(n), decoding.get(n)) for n in names}
    finally:
        pool.shutdown(wait=False)  # the decoding goes on; the threads end with it


def fetch_pixels(job: JobInput) -> None:
    """The pixels of every pending image of job, read on this (the main)
    thread; errors wait in the images for whoever asks for their pixels."""
    for image in job.images.values():
        if isinstance(image, PendingImage):
            image.fetch()
