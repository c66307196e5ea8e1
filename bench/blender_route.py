"""The route Blender users know, for the benchmark (runs inside Blender).

    blender --background --factory-startup --python-exit-code 1 --python bench/blender_route.py -- \\
        IN.obj|IN.glb OUT_DIR [--samples 4] [--angle 66] [--island-margin 0.001] [--margin 16]

Imports the scan, Smart UV Projects every face into a new UV map, bakes the
old base colour (read through the old UV map) with a Cycles EMIT bake into a
new image with as many texels as the input's pages together (denoising off),
saves it, rewires the material to the new image and map, drops the old map and
exports the model in the input's format. glTF input is imported with
merge_vertices (glTF splits vertices at every UV seam). Writes to OUT_DIR: the model, the
baked PNG, route.json (seconds per stage, sizes) and route_arrays.npz (corner
positions as read, old and new per-corner UVs, per-face "textured" flag) so the
benchmark measures this route with the same code as Atlas Defrag's.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import bpy
import numpy as np


def parse(argv):
    p = argparse.ArgumentParser(prog="blender_route.py")
    p.add_argument("input")
    p.add_argument("out_dir")
    p.add_argument("--samples", type=int, default=4)
    p.add_argument("--angle", type=float, default=66.0, help="Smart UV Project angle limit (degrees)")
    p.add_argument("--island-margin", type=float, default=0.001)
    p.add_argument("--margin", type=int, default=16, help="bake margin (texels)")
    return p.parse_args(argv)


def import_scan(path):
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        bpy.ops.wm.obj_import(filepath=path)
    elif ext in (".glb", ".gltf"):
        if "bool" not in np.__dict__:
            np.bool = bool  # Debian's Blender 3.4 glTF importer still uses the alias
        # glTF stores a vertex per UV seam corner: without merging them Smart UV Project
        # cannot join faces across the old seams, which no careful user would accept.
        bpy.ops.import_scene.gltf(filepath=path, merge_vertices=True)
    else:
        raise RuntimeError(f"unsupported input {ext}")
    return [o for o in bpy.context.scene.objects if o.type == "MESH"]


def base_colour_node(mat):
    """The image node feeding Base Color (directly or through other nodes), if any."""
    if not mat or not mat.use_nodes:
        return None
    tree = mat.node_tree
    bsdf = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)
    if bsdf is None:
        return None
    stack, seen = [bsdf.inputs["Base Color"]], set()
    while stack:
        sock = stack.pop()
        for link in sock.links:
            node = link.from_node
            if node.name in seen:
                continue
            seen.add(node.name)
            if node.bl_idname == "ShaderNodeTexImage" and node.image:
                return node
            stack.extend(i for i in node.inputs if i.is_linked)
    return None


def corner_arrays(me, layer_name):
    uv = np.empty(len(me.loops) * 2, dtype=np.float32)
    me.uv_layers[layer_name].data.foreach_get("uv", uv)
    return uv.reshape(-1, 3, 2)


def main():
    args = parse(sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else [])
    os.makedirs(args.out_dir, exist_ok=True)
    stem = os.path.splitext(os.path.basename(args.input))[0]
    ext = os.path.splitext(args.input)[1].lower()
    seconds = {}
    t0 = time.perf_counter()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    meshes = import_scan(os.path.abspath(args.input))
    bpy.ops.object.select_all(action="DESELECT")
    for o in meshes:
        o.select_set(True)
    bpy.context.view_layer.objects.active = meshes[0]
    if len(meshes) > 1:
        bpy.ops.object.join()
    obj = bpy.context.view_layer.objects.active
    me = obj.data
    seconds["import"] = time.perf_counter() - t0

    if any(p.loop_total != 3 for p in me.polygons):
        raise RuntimeError("the benchmark compares triangles only; this scan has polygons")
    old_name = me.uv_layers.active.name
    old_uv = corner_arrays(me, old_name)
    co = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", co)
    tri = np.empty(len(me.polygons) * 3, dtype=np.int64)
    me.polygons.foreach_get("vertices", tri)
    corners = co.reshape(-1, 3)[tri.reshape(-1, 3)]
    mat_index = np.empty(len(me.polygons), dtype=np.int64)
    me.polygons.foreach_get("material_index", mat_index)

    # Old texel count: every distinct base colour image, once.
    images = {}
    for mat in me.materials:
        node = base_colour_node(mat)
        if node is not None:
            images[node.image.name] = tuple(node.image.size)
    texels = sum(w * h for w, h in images.values())
    side = max(16, int(round(math.sqrt(texels))))

    # Smart UV Project into a new map (the old one stays for the bake).
    t = time.perf_counter()
    new_layer = me.uv_layers.new(name="SmartUV")
    me.uv_layers.active = new_layer
    me.uv_layers[old_name].active_render = True
    bpy.ops.object.mode_set(mode="EDIT")
    bpy.ops.mesh.select_all(action="SELECT")
    bpy.ops.uv.smart_project(angle_limit=math.radians(args.angle), island_margin=args.island_margin)
    bpy.ops.object.mode_set(mode="OBJECT")
    seconds["smart_uv"] = time.perf_counter() - t

    # Emission bake of the old colour, read through the old map, into the new image.
    t = time.perf_counter()
    target = bpy.data.images.new(f"{stem}_smartuv", side, side, alpha=False)
    textured = np.zeros(len(me.materials) or 1, dtype=bool)
    for i, mat in enumerate(me.materials):
        if mat is None:
            continue
        mat.use_nodes = True
        tree = mat.node_tree
        out = next((n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"), None)
        if out is None:
            out = tree.nodes.new("ShaderNodeOutputMaterial")
        emit = tree.nodes.new("ShaderNodeEmission")
        src = base_colour_node(mat)
        if src is not None:
            textured[i] = True
            uvnode = tree.nodes.new("ShaderNodeUVMap")
            uvnode.uv_map = old_name
            tree.links.new(uvnode.outputs["UV"], src.inputs["Vector"])
            tree.links.new(src.outputs["Color"], emit.inputs["Color"])
        else:
            emit.inputs["Color"].default_value = (0, 0, 0, 1)
        tree.links.new(emit.outputs["Emission"], out.inputs["Surface"])
        node = tree.nodes.new("ShaderNodeTexImage")
        node.image = target
        for n in tree.nodes:
            n.select = False
        node.select = True
        tree.nodes.active = node
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = args.samples
    scene.cycles.use_denoising = False  # Debian's Blender has no OpenImageDenoise: black bakes otherwise
    scene.view_settings.view_transform = "Standard"
    scene.render.bake.margin = args.margin
    scene.render.bake.use_clear = True
    scene.render.bake.target = "IMAGE_TEXTURES"
    bpy.ops.object.bake(type="EMIT", margin=args.margin, use_clear=True)
    seconds["bake"] = time.perf_counter() - t

    # Save the image, point the material at it through the new map, export.
    t = time.perf_counter()
    png = os.path.join(args.out_dir, f"{stem}_smartuv.png")
    target.filepath_raw = png
    target.file_format = "PNG"
    target.save()
    target.source = "FILE"
    seconds["save_image"] = time.perf_counter() - t

    new_uv = corner_arrays(me, "SmartUV")
    np.savez(os.path.join(args.out_dir, "route_arrays.npz"), corners=corners, old_uv=old_uv, new_uv=new_uv,
             textured=textured[np.minimum(mat_index, len(textured) - 1)], import_format=ext)

    t = time.perf_counter()
    baked = bpy.data.materials.new(f"{stem}_smartuv")
    baked.use_nodes = True
    tree = baked.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = target
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    me.materials.clear()
    me.materials.append(baked)
    me.uv_layers.remove(me.uv_layers[old_name])
    out_model = os.path.join(args.out_dir, f"{stem}_smartuv{'.obj' if ext == '.obj' else '.glb'}")
    if ext == ".obj":
        bpy.ops.wm.obj_export(filepath=out_model, export_selected_objects=True, export_uv=True,
                              export_normals=True, export_materials=True, path_mode="STRIP",
                              forward_axis="NEGATIVE_Z", up_axis="Y")
    else:
        bpy.ops.export_scene.gltf(filepath=out_model, export_format="GLB", use_selection=True)
    seconds["export"] = time.perf_counter() - t
    seconds["total"] = time.perf_counter() - t0
    with open(os.path.join(args.out_dir, "route.json"), "w") as f:
        json.dump({"seconds": seconds, "image_size": [side, side], "input_texels": texels,
                   "faces": len(me.polygons), "samples": args.samples, "angle_limit": args.angle,
                   "island_margin": args.island_margin, "bake_margin": args.margin,
                   "blender": bpy.app.version_string, "image": png, "model": out_model}, f, indent=2)
    print(f"blender_route: {stem}: " + ", ".join(f"{k} {v:.2f}" for k, v in seconds.items()))


main()
