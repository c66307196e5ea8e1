# SPDX-License-Identifier: MIT
"""A textured PLY scan into Blender, for the batch entry and File > Import.

Blender's own PLY importers read UVs only per vertex (3.4: `s t` only), so
the per-face `texcoord` lists that MeshLab and OpenMVS write would be lost,
and the 3.4 importer takes seconds per million faces. ply_io reads the file
into arrays; this module writes them into one mesh in a block of
foreach_set calls, with a material per texture named in the header.
"""

from __future__ import annotations

import os

import bpy
import numpy as np

from . import compat, ply_io


def _mesh(name: str, mesh: ply_io.PlyMesh):
    """One triangle per face, the UVs (when the file has any) in map 'UVMap',
    vertex colours (when it has any) in the colour attribute 'Col'. (Its
    normals are set once the mesh is valid: see import_ply.)"""
    me = bpy.data.meshes.new(name)
    count = len(mesh.triangles)
    me.vertices.add(len(mesh.positions))
    me.loops.add(3 * count)
    me.polygons.add(count)
    me.vertices.foreach_set("co", mesh.positions.astype(np.float32).ravel())
    if bpy.app.version < (4, 0, 0):  # read-only since 4.0, where loop_start alone sets it
        me.polygons.foreach_set("loop_total", np.full(count, 3, dtype=np.int32))
    me.polygons.foreach_set("loop_start", np.arange(0, 3 * count, 3, dtype=np.int32))
    me.loops.foreach_set("vertex_index", mesh.triangles.astype(np.int32).ravel())
    if mesh.uvs is not None:
        compat.set_uv_coordinates(me.uv_layers.new(name="UVMap"), mesh.uvs)
    if mesh.colours is not None:
        colours = me.color_attributes.new(name="Col", type="BYTE_COLOR", domain="POINT")
        colours.data.foreach_set("color_srgb", mesh.colours.ravel())
    me.update(calc_edges=True)
    return me


def image_material(image_path: str):
    """A new material with the image (loaded once) on Base Color; ValueError
    when Blender cannot open the file."""
    try:
        img = bpy.data.images.load(image_path, check_existing=True)
    except RuntimeError as exc:
        raise ValueError(f"cannot open the texture {image_path}: {exc}") from exc
    mat = bpy.data.materials.new(ply_io.readable(os.path.splitext(os.path.basename(image_path))[0]))
    if bpy.app.version < (5, 0, 0):  # always on in 5.0, where the property is deprecated
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.location = (bsdf.location[0] - 400, bsdf.location[1])
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _assign_materials(me, mesh: ply_io.PlyMesh, folder: str) -> list:
    """Material k for the k-th texture that exists; faces whose texture is
    missing (or out of range) get an untextured material, and are left as
    they are by the defragmentation. Returns the texture names missing."""
    found, face_material, missing = ply_io.face_textures(mesh, folder)
    for path in found:
        me.materials.append(image_material(path))
    if not found:
        return missing
    if (face_material < 0).any():
        face_material[face_material < 0] = len(found)
        me.materials.append(bpy.data.materials.new("untextured"))
    me.polygons.foreach_set("material_index", face_material.astype(np.int32))
    return missing


def import_ply(path: str):
    """(the new object, linked to the active collection; the texture files
    the header names that are missing; notes on faces the file leaves
    untextured). ValueError saying what is wrong with the file; nothing is
    then added."""
    with open(path, "rb") as f:
        mesh = ply_io.read(f.read())
    name = os.path.splitext(os.path.basename(path))[0]
    me = _mesh(name, mesh)
    try:
        missing = _assign_materials(me, mesh, os.path.dirname(path))
    except BaseException:
        bpy.data.meshes.remove(me)
        raise
    # Faces that name a vertex twice, and repeated faces, go as Blender's
    # own importers drop them: later steps expect a valid mesh.
    me.validate(clean_customdata=False)
    if mesh.normals is not None:  # as the file shades it
        compat.set_vertex_normals(me, mesh.normals)
    obj = bpy.data.objects.new(name, me)
    (bpy.context.collection or bpy.context.scene.collection).objects.link(obj)
    # As an import operator does: without it bpy 4.5's OBJ export, which
    # reads the evaluated scene, finds the object empty.
    bpy.context.view_layer.update()
    return obj, missing, mesh.notes
