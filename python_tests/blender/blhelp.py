# SPDX-License-Identifier: MIT
"""Helpers shared by the Blender tests: run inside Blender 3.4 (by
bl_runner.py) and inside the bpy 4.5 module (by pytest). bpy + numpy only."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import bpy
import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]


def models_dir() -> Path:
    env = os.environ.get("ATLAS_MODELS_DIR")
    if env:
        return Path(env)
    for cand in (REPO.parent / "shared" / "models", Path("/work/shared/models")):
        if cand.is_dir():
            return cand
    return REPO.parent / "shared" / "models"


MODELS = {
    "tetra": "tetra_miniature/teTra-Mk5-miniature-model.obj",
    "smithsonian": "smithsonian_usnm1145291/usnm_1145291.glb",
    "meshroom": "meshroom_esp32cam/texturedMesh.obj",
}

ASSIMP = Path("/usr/share/assimp/models")


try:  # under pytest a missing scan skips the test; inside Blender, bl_runner reports the skip
    from pytest import skip as _skip
    _SkipBase = _skip.Exception
except ImportError:
    _SkipBase = Exception


class MissingModel(_SkipBase):
    """A shared scan is not there."""


def model_path(key: str) -> str:
    path = models_dir() / MODELS[key]
    if not path.is_file():
        raise MissingModel(f"real scan {path} is missing (the shared models; set ATLAS_MODELS_DIR)")
    return str(path)


def openmvs_style_ply(path) -> int:
    """The tetra scan as OpenMVS and MeshLab write PLY: binary, shared
    vertices, 6 UV values per face and a texnumber (-1: no texture), which
    Blender's own PLY importers drop."""
    import numpy as np

    from atlas_defrag import _native

    obj = _native.read_obj(model_path("tetra"))
    textured = obj["texcoord_index"][:, 0] >= 0
    face = np.zeros(len(obj["triangles"]), np.dtype([("n", "u1"), ("i", "<i4", (3,)), ("m", "u1"),
                                                     ("uv", "<f4", (6,)), ("tex", "<i4")]))
    face["n"], face["i"], face["m"], face["tex"] = 3, obj["triangles"], 6, np.where(textured, 0, -1)
    face["uv"] = obj["texcoords"][np.maximum(obj["texcoord_index"], 0)].reshape(-1, 6)
    texture = os.path.join(os.path.dirname(model_path("tetra")), "textures", "textured_0_v2.jpg")
    head = (f"ply\nformat binary_little_endian 1.0\ncomment TextureFile {texture}\n"
            f"element vertex {len(obj['positions'])}\nproperty double x\nproperty double y\nproperty double z\n"
            f"element face {len(face)}\nproperty list uchar int vertex_indices\n"
            "property list uchar float texcoord\nproperty int texnumber\nend_header\n")
    path.write_bytes(head.encode() + np.asarray(obj["positions"], "<f8").tobytes() + face.tobytes())
    return int(textured.sum())


# --------------------------------------------------------------------------- scenes
def reset() -> None:
    """An empty scene. (read_homefile keeps enabled add-ons, unlike
    read_factory_settings; Blender runs with --factory-startup anyway.)"""
    bpy.ops.wm.read_homefile(use_empty=True)


def import_model(path: str):
    """Imports a model, makes its first mesh active and selected; returns it."""
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        bpy.ops.wm.obj_import(filepath=path)
    elif ext in (".glb", ".gltf"):
        if bpy.app.version < (4, 0, 0) and "bool" not in np.__dict__:
            np.bool = bool  # Blender 3.x glTF importer with numpy >= 1.24
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".ply":
        if "ply_import" in dir(bpy.ops.wm):
            bpy.ops.wm.ply_import(filepath=path)
        else:
            bpy.ops.import_mesh.ply(filepath=path)
    else:
        raise ValueError(path)
    meshes = [o for o in bpy.context.scene.objects if o.type == "MESH"]
    obj = max(meshes, key=lambda o: len(o.data.polygons))
    make_active(obj)
    return obj


def make_active(obj) -> None:
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    if obj is not None:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = obj


def textured_plane(name="Plane", image_size=(64, 32), uv_maps=1, source="GENERATED", float_buffer=False):
    """A 2x2-quad grid with one image texture on Base Color; returns the object."""
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=3, y_subdivisions=3, size=2.0)
    obj = bpy.context.active_object
    obj.name = name
    me = obj.data
    while len(me.uv_layers) < uv_maps:
        me.uv_layers.new(name=f"UVMap.{len(me.uv_layers):03d}")
    img = bpy.data.images.new(name + "_tex", *image_size, alpha=True, float_buffer=float_buffer,
                              tiled=(source == "TILED"))
    if source == "TILED":
        img.tiles.new(tile_number=1002)
    rng = np.random.default_rng(1)
    if source != "TILED":
        img.pixels.foreach_set(rng.random(image_size[0] * image_size[1] * 4).astype(np.float32))
        img.pack()
    mat = bpy.data.materials.new(name + "_mat")
    if bpy.app.version < (5, 0, 0):  # 5.0: always on, the property is deprecated
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    me.materials.append(mat)
    return obj


# --------------------------------------------------------------------------- snapshots
def _h(arr) -> str:
    return hashlib.sha256(np.ascontiguousarray(arr).tobytes()).hexdigest()[:16]


def uv_hash(me, name) -> str:
    arr = np.empty(len(me.loops) * 2, dtype=np.float32)
    me.uv_layers[name].data.foreach_get("uv", arr)
    return _h(arr)


def image_state(img) -> dict:
    d = {"name": img.name, "source": img.source, "size": tuple(img.size),
         "colorspace": img.colorspace_settings.name, "is_float": bool(img.is_float),
         "filepath": img.filepath, "packed": img.packed_file is not None,
         "is_dirty": bool(img.is_dirty)}
    if img.source in ("FILE", "GENERATED") and img.size[0] > 0:
        arr = np.empty(img.size[0] * img.size[1] * img.channels, dtype=np.float32)
        img.pixels.foreach_get(arr)
        d["pixels"] = _h(arr)
    return d


def tree_state(mat) -> dict:
    if mat is None or mat.node_tree is None:
        return {"use_nodes": False}
    nodes = []
    for n in mat.node_tree.nodes:
        nodes.append((n.name, n.bl_idname, n.image.name if getattr(n, "image", None) else None,
                      getattr(n, "uv_map", None), getattr(n, "space", None)))
    links = sorted((lk.from_node.name, lk.from_socket.identifier, lk.to_node.name, lk.to_socket.identifier)
                   for lk in mat.node_tree.links)
    return {"nodes": sorted(nodes), "links": links}


def object_state(obj_name: str, pixels=True) -> dict:
    """Everything the operator may touch, hashed: compare before/after."""
    obj = bpy.data.objects[obj_name]
    if obj.mode == "EDIT":
        # Mesh arrays are stale while editing (and 4.x hides UV data): hash a synced copy.
        obj.update_from_editmode()
        copy = obj.data.copy()
        try:
            return _object_state(obj, copy, pixels)
        finally:
            bpy.data.meshes.remove(copy)
    return _object_state(obj, obj.data, pixels)


def _object_state(obj, me, pixels) -> dict:
    d = {"mode": obj.mode, "mesh": obj.data.name}
    d["uv_maps"] = [uv.name for uv in me.uv_layers]
    d["uv_active"] = me.uv_layers.active.name if me.uv_layers.active else None
    d["uv_render"] = [uv.name for uv in me.uv_layers if uv.active_render]
    d["uv_hash"] = {uv.name: uv_hash(me, uv.name) for uv in me.uv_layers}
    for attr, n, dtype, arr_len in (("vertices", "co", np.float32, 3), ("polygons", "material_index", np.int32, 1),
                                    ("loops", "vertex_index", np.int32, 1)):
        coll = getattr(me, attr)
        arr = np.empty(len(coll) * arr_len, dtype=dtype)
        coll.foreach_get(n, arr)
        d[f"{attr}.{n}"] = _h(arr)
    d["slots"] = [(s.material.name if s.material else None, s.link) for s in obj.material_slots]
    d["materials"] = {m.name: tree_state(m) for m in bpy.data.materials}
    d["images"] = sorted(bpy.data.images.keys())
    if pixels:
        d["image_state"] = {i.name: image_state(i) for i in bpy.data.images
                            if i.type == "IMAGE" and i.source != "VIEWER"}
    return d


def image_nodes(mat):
    return [n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"]


def vector_uv_map(node):
    """Name of the UV map a (rewired) image node reads through a UV Map node."""
    sock = node.inputs["Vector"]
    if not sock.is_linked:
        return None
    src = sock.links[0].from_node
    return src.uv_map if src.bl_idname == "ShaderNodeUVMap" else "?" + src.bl_idname


def image_variance(img) -> float:
    arr = np.empty(img.size[0] * img.size[1] * img.channels, dtype=np.float32)
    img.pixels.foreach_get(arr)
    rgb = arr.reshape(-1, img.channels)[:, :3]
    return float(rgb.std())


def undo_context():
    """A context in which ed.undo / ed.undo_push work, also in background."""
    win = bpy.context.window_manager.windows[0]
    return bpy.context.temp_override(window=win, screen=win.screen, area=win.screen.areas[0])


def undo_push(message="test"):
    with undo_context():
        bpy.ops.ed.undo_push(message=message)


def undo():
    with undo_context():
        bpy.ops.ed.undo()
