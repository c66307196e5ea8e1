# SPDX-License-Identifier: MIT
"""Differences between Blender 3.x and 4.x that the other modules must not care about."""

from __future__ import annotations

import contextlib

import bpy
import numpy as np


# Blender allows at most this many UV maps on a mesh (MAX_MTFACE).
MAX_UV_MAPS = 8
# The longest UV map name (UTF-8 bytes) a UV Map node or a modifier holds;
# 4.x lets the maps themselves have longer names.
NAME_BYTES = 63

# Principled BSDF input names (3.x and 4.x) -> role names used by the job.
PRINCIPLED_ROLES = {
    "Base Color": "base_color",
    "Metallic": "metallic",
    "Roughness": "roughness",
    "Alpha": "alpha",
    "Normal": "normal",
    "Emission": "emission",  # 3.x
    "Emission Color": "emission",  # 4.x
    "Emission Strength": "emission_strength",
    "Specular": "specular",  # 3.x
    "Specular IOR Level": "specular",  # 4.x
    "Clearcoat Normal": "coat_normal",  # 3.x
    "Coat Normal": "coat_normal",  # 4.x
    "Subsurface Color": "base_color",  # 3.x: glTF and OBJ feed it with the base colour
}


def input_role(socket_name: str) -> str:
    role = PRINCIPLED_ROLES.get(socket_name)
    if role is None:
        role = socket_name.strip().lower().replace(" ", "_") or "other"
    return role


def node_tree(mat):
    """The material's node tree when it shades with nodes, else None.
    Material.use_nodes is deprecated in 5.0 (always on) and goes in 6.0."""
    if mat is None or mat.node_tree is None:
        return None
    if bpy.app.version >= (5, 0, 0) or mat.use_nodes:
        return mat.node_tree
    return None


def calc_loop_triangles(mesh) -> None:
    # 4.x keeps loop triangles up to date lazily; the call still exists in 4.5.
    fn = getattr(mesh, "calc_loop_triangles", None)
    if fn is not None:
        fn()


def is_gltf_output_group(node) -> bool:
    """The glTF importer's group carrying Occlusion ("glTF Settings" in old
    versions, "glTF Material Output" since 3.x)."""
    tree = getattr(node, "node_tree", None)
    return node.bl_idname == "ShaderNodeGroup" and tree is not None and "gltf" in tree.name.lower()


def temp_override(context, **kwargs):
    """context.temp_override (3.2+), with only the keys the caller provides."""
    kwargs = {k: v for k, v in kwargs.items() if v is not None}
    if hasattr(context, "temp_override"):
        return context.temp_override(**kwargs)
    return contextlib.nullcontext()


def set_vertex_normals(me, normals: np.ndarray) -> None:
    """Shades me smooth with normals (V, 3) as its custom normals (a zero or
    non-finite one: Blender's own). Before 4.1 custom normals show only with
    Auto Smooth on."""
    me.polygons.foreach_set("use_smooth", np.ones(len(me.polygons), dtype=bool))
    if hasattr(me, "use_auto_smooth"):
        me.use_auto_smooth = True
    clean = np.where(np.isfinite(normals).all(axis=1, keepdims=True), normals, 0.0)
    me.normals_split_custom_set_from_vertices(clean)


def set_colorspace(image, name: str) -> None:
    try:
        image.colorspace_settings.name = name
    except TypeError:
        # A colour space this Blender does not know (file from another version).
        pass


def status_text_set(context, text) -> None:
    ws = getattr(context, "workspace", None)
    if ws is not None and hasattr(ws, "status_text_set"):
        try:
            ws.status_text_set(text)
        except Exception:
            pass


def uv_coordinates(layer) -> np.ndarray:
    """(corners * 2,) float32 coordinates of a UV map. 3.5+ keeps them in a
    float2 attribute, which layer.uv reads in one copy; its layer.data reads
    corner by corner."""
    out = np.empty(len(layer.data) * 2, dtype=np.float32)
    if hasattr(layer, "uv"):
        layer.uv.foreach_get("vector", out)
    else:
        layer.data.foreach_get("uv", out)
    return out


def set_uv_coordinates(layer, values: np.ndarray) -> None:
    """Sets a UV map's coordinates from (corners, 2) or (corners * 2,) values."""
    flat = np.ascontiguousarray(values, dtype=np.float32).reshape(-1)
    if hasattr(layer, "uv"):
        layer.uv.foreach_set("vector", flat)
    else:
        layer.data.foreach_set("uv", flat)


# Per-corner flags of a UV map: 4.x keeps them in attributes named after the
# map (created on first write, renamed with it), 3.x in the map's loop data.
_UV_FLAGS_4 = (("pin", ".pn."), ("vertex_selection", ".vs."), ("edge_selection", ".es."))
_UV_FLAGS_3 = ("pin_uv", "select", "select_edge")


def uv_flags(me, name: str) -> dict:
    """{flag: (corners,) bool} of the pins and UV selection of me's UV map
    name; reading creates no attribute."""
    layer = me.uv_layers[name]
    out = {}
    if not hasattr(layer, "pin"):
        for flag in _UV_FLAGS_3:
            out[flag] = np.zeros(len(layer.data), dtype=bool)
            layer.data.foreach_get(flag, out[flag])
        return out
    for flag, prefix in _UV_FLAGS_4:
        out[flag] = np.zeros(len(me.loops), dtype=bool)
        attribute = me.attributes.get(prefix + name)
        if attribute is not None:
            attribute.data.foreach_get("value", out[flag])
    return out


def set_uv_flags(me, name: str, flags: dict) -> None:
    """Sets what uv_flags gave on me's UV map name (as many corners),
    creating no attribute to hold flags that are all off."""
    layer = me.uv_layers[name]
    for flag, values in flags.items():
        if not hasattr(layer, "pin"):
            layer.data.foreach_set(flag, values)
            continue
        attribute_name = dict(_UV_FLAGS_4)[flag] + name
        attribute = me.attributes.get(attribute_name)
        if attribute is None and values.any():
            attribute = me.attributes.new(attribute_name, "BOOLEAN", "CORNER")
        if attribute is not None:
            attribute.data.foreach_set("value", values)
