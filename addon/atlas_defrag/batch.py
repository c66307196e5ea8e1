# SPDX-License-Identifier: MIT
"""Batch entry: defragments one model per Blender process.

One model (inside Blender)::

    blender --background --factory-startup --python-exit-code 1 \\
        --python .../atlas_defrag/batch.py -- IN OUT [options] [--report report.json]

IN is .obj, .gltf, .glb or .ply; OUT is .obj (writes OBJ + MTL + PNG beside it)
or .glb / .gltf. The exit code is 0 on success (or when skipped), 1 on failure
with the reason on stderr, 2 on bad arguments.

Several models (any Python, Blender included): one Blender process per model,
``--jobs`` at once, skipping those whose output exists::

    python3 .../atlas_defrag/batch.py --out-dir OUT_DIR [--format glb|obj] [--jobs 2] IN... [options]

IN may be files or folders (their models, not recursive). GNU parallel does the
same with the single-model form and --skip-existing.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

INPUT_EXTS = (".obj", ".gltf", ".glb", ".ply")
OUTPUT_EXTS = (".obj", ".glb", ".gltf")


class BatchError(Exception):
    pass


# --------------------------------------------------------------------------- arguments
def _schema():
    """The option schema (options.py). Run by path, the many-models form
    loads the file alone: it needs the standard library only (the package
    would import numpy)."""
    if __package__:
        return importlib.import_module(__package__ + ".options")
    name = "atlas_defrag_options"
    if name not in sys.modules:
        path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "options.py")
        spec = importlib.util.spec_from_file_location(name, path)
        sys.modules[name] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules[name])
    return sys.modules[name]


def _add_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("defragmentation options")
    _schema().add_arguments(g)
    g.add_argument("--uv-map", default=None, help="UV map to defragment (default: the active one)")
    g.add_argument("--texture", default=None,
                   help="image to use for meshes without an image texture (e.g. PLY)")
    g.add_argument("--keep-source-uv", action="store_true",
                   help="keep the original UV map in the output (as a second UV set)")
    g.add_argument("--skip-existing", action="store_true", help="do nothing if OUT exists")


def single_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="batch.py", description="Defragment the texture atlas of one model.")
    p.add_argument("input", help="model: .obj, .gltf, .glb or .ply")
    p.add_argument("output", help="result: .obj (+ .mtl + .png) or .glb / .gltf")
    p.add_argument("--report", default=None, help="write a JSON report here")
    _add_options(p)
    return p


def multi_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="batch.py", description="Defragment many models, one Blender each.")
    p.add_argument("inputs", nargs="+", help="model files or folders")
    p.add_argument("--out-dir", required=True)
    p.add_argument("--format", choices=("glb", "obj"), default="glb")
    p.add_argument("--jobs", "-j", type=int, default=max(1, (os.cpu_count() or 2) // 2))
    p.add_argument("--blender", default=None, help="Blender executable (default: $BLENDER or blender)")
    _add_options(p)
    return p


def _script_argv(argv=None):
    """The script's arguments: those after '--' (as Blender passes them)."""
    if argv is not None:
        return list(argv)
    if "--" in sys.argv:
        return sys.argv[sys.argv.index("--") + 1:]
    return sys.argv[1:]


# --------------------------------------------------------------------------- inside Blender
def _package():
    """The add-on package, whether this file was imported or run by path."""
    if __package__:
        return importlib.import_module(__package__)
    here = os.path.dirname(os.path.abspath(__file__))
    parent, name = os.path.split(here)
    if parent not in sys.path:
        sys.path.insert(0, parent)
    return importlib.import_module(name)


def _numpy_bool_alias():
    # Blender 3.x glTF add-on uses numpy.bool, removed in numpy 1.24.
    try:
        import numpy
        if "bool" not in numpy.__dict__:
            numpy.bool = bool
    except ImportError:
        pass


def _has_op(module, name: str) -> bool:
    # hasattr() is always true on bpy.ops modules: ask for the listing.
    return name in dir(module)


def import_model(path: str):
    import bpy
    ext = os.path.splitext(path)[1].lower()
    before = set(bpy.data.objects)
    if ext == ".obj":
        if _has_op(bpy.ops.wm, "obj_import"):
            bpy.ops.wm.obj_import(filepath=path)
        else:
            bpy.ops.import_scene.obj(filepath=path)
    elif ext in (".gltf", ".glb"):
        _numpy_bool_alias()
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".ply":
        if _has_op(bpy.ops.wm, "ply_import"):
            bpy.ops.wm.ply_import(filepath=path)
        else:
            bpy.ops.import_mesh.ply(filepath=path)
    else:
        raise BatchError(f"unsupported input format '{ext}' (use {', '.join(INPUT_EXTS)})")
    new = [o for o in bpy.data.objects if o not in before]
    if not any(o.type == "MESH" for o in new):
        raise BatchError(f"no mesh imported from {path}")
    return new


def _ply_texture(path: str):
    """The image a PLY header names ('comment TextureFile x.png'), if any."""
    try:
        with open(path, "rb") as f:
            for _ in range(200):
                line = f.readline()
                if not line or line.strip() == b"end_header":
                    break
                parts = line.decode("latin-1").split(None, 2)
                if len(parts) == 3 and parts[0] == "comment" and parts[1].lower() == "texturefile":
                    tex = os.path.join(os.path.dirname(path), parts[2].strip())
                    return tex if os.path.exists(tex) else None
    except OSError:
        return None
    return None


def _give_texture(obj, image_path: str):
    """A material with the image on Base Color, for meshes that have none."""
    import bpy
    img = bpy.data.images.load(image_path, check_existing=True)
    mat = bpy.data.materials.new(os.path.splitext(os.path.basename(image_path))[0])
    if bpy.app.version < (5, 0, 0):  # always on in 5.0, where the property is deprecated
        mat.use_nodes = True
    tree = mat.node_tree
    bsdf = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    tex = tree.nodes.new("ShaderNodeTexImage")
    tex.image = img
    tex.location = (bsdf.location[0] - 400, bsdf.location[1])
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    obj.data.materials.clear()
    obj.data.materials.append(mat)


def _has_image_texture(pkg, obj) -> bool:
    try:
        pkg.read_bpy.check_object(obj)
    except pkg.DefragError:
        return False
    for slot in obj.material_slots:
        tree = pkg.compat.node_tree(slot.material)
        if tree is not None and any(n.bl_idname == "ShaderNodeTexImage" and n.image for n in tree.nodes):
            return True
    return False


def _drop_source_uv(obj, name: str, report: dict) -> None:
    me = obj.data
    layer = me.uv_layers.get(name)
    if layer is None:
        return
    still_used = []
    for slot in obj.material_slots:
        mat = slot.material
        if mat and mat.node_tree:  # nodes that would name the removed map, used or not
            for n in mat.node_tree.nodes:
                if getattr(n, "uv_map", None) == name:
                    still_used.append(f"{mat.name}/{n.name}")
    me.uv_layers.remove(layer)
    if still_used:
        report.setdefault("warnings", []).append(
            "source UV map removed although these nodes named it: " + ", ".join(still_used))


def export_model(path: str, objects) -> None:
    import bpy
    ext = os.path.splitext(path)[1].lower()
    for o in bpy.context.view_layer.objects:
        o.select_set(o in objects)
    if ext == ".obj":
        bpy.ops.wm.obj_export(filepath=path, export_selected_objects=True, export_uv=True,
                              export_normals=True, export_materials=True, path_mode="STRIP",
                              forward_axis="NEGATIVE_Z", up_axis="Y")
    elif ext in (".glb", ".gltf"):
        _numpy_bool_alias()
        kw = dict(filepath=path, export_format="GLB" if ext == ".glb" else "GLTF_EMBEDDED",
                  use_selection=True)
        try:
            bpy.ops.export_scene.gltf(**kw)
        except TypeError:
            kw.pop("use_selection")
            bpy.ops.export_scene.gltf(**kw)
    else:
        raise BatchError(f"unsupported output format '{ext}' (use {', '.join(OUTPUT_EXTS)})")


def run_one(args) -> dict:
    """Imports args.input, defragments every textured mesh, exports args.output."""
    pkg = _package()
    t0 = time.perf_counter()
    src, dst = os.path.abspath(args.input), os.path.abspath(args.output)
    objects = _import_input(src, dst)
    t_import = time.perf_counter() - t0
    meshes = [o for o in objects if o.type == "MESH"]
    texture = args.texture or (_ply_texture(src) if src.lower().endswith(".ply") else None)
    if texture:
        _give_missing_textures(pkg, meshes, os.path.abspath(texture))
    out_dir = os.path.dirname(dst) or "."
    os.makedirs(out_dir, exist_ok=True)
    tmp = tempfile.mkdtemp(prefix=".atlas_defrag_", dir=out_dir)
    report = {"input": src, "output": dst, "objects": [], "warnings": []}
    try:
        _defragment_meshes(pkg, args, meshes, tmp, report)
        t_export = time.perf_counter()
        _export_and_move(objects, tmp, dst)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    report["seconds"] = {"import": t_import, "export": time.perf_counter() - t_export,
                         "total": time.perf_counter() - t0}
    report["status"] = "ok"
    return report


def _import_input(src: str, dst: str):
    """The objects of src, in an empty scene; refuses what cannot be written."""
    import bpy
    if not os.path.isfile(src):
        raise BatchError(f"input not found: {src}")
    out_ext = os.path.splitext(dst)[1].lower()
    if out_ext not in OUTPUT_EXTS:
        raise BatchError(f"unsupported output format '{out_ext}' (use {', '.join(OUTPUT_EXTS)})")
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return import_model(src)


def _give_missing_textures(pkg, meshes, texture: str) -> None:
    for o in meshes:
        if not _has_image_texture(pkg, o) and len(o.data.uv_layers):
            _give_texture(o, texture)


def _defragment_meshes(pkg, args, meshes, image_dir: str, report: dict) -> None:
    """Each mesh once (linked duplicates share it); its report into report['objects']."""
    done_meshes = set()
    errors = []
    shared = _shared_materials(meshes)
    options = {o.name: getattr(args, o.name) for o in _schema().SCHEMA}
    for o in meshes:
        if o.data.name in done_meshes:
            continue
        try:
            r = pkg.defragment(o, uv_map=args.uv_map, storage="SAVE", image_dir=image_dir,
                               duplicate_materials=any(s.material and s.material.name in shared
                                                       for s in o.material_slots),
                               **options)
        except pkg.DefragError as exc:
            errors.append(f"{o.name}: {exc}")
            continue
        done_meshes.add(o.data.name)
        if not args.keep_source_uv:
            _drop_source_uv(o, r["source_uv_map"], r)
        report["objects"].append(pkg.api.plain(r))
    if not report["objects"]:
        raise BatchError("nothing to defragment: " + "; ".join(errors or ["no mesh"]))
    report["warnings"].extend(errors)


def _shared_materials(meshes) -> set:
    """Materials used by several objects: they are duplicated, so each object gets its own."""
    users = {}
    for o in meshes:
        for s in o.material_slots:
            if s.material:
                users[s.material.name] = users.get(s.material.name, 0) + 1
    return {name for name, count in users.items() if count > 1}


def _export_and_move(objects, tmp: str, dst: str) -> None:
    """Exports into tmp, then moves the files beside dst: images next to an
    OBJ (a glTF carries them), the model file last, so that an existing OUT
    always means a finished run."""
    out_dir = os.path.dirname(dst) or "."
    tmp_out = os.path.join(tmp, os.path.basename(dst))
    export_model(tmp_out, objects)
    is_obj = dst.lower().endswith(".obj")
    for name in sorted(os.listdir(tmp)):
        if name == os.path.basename(dst):
            continue
        if is_obj or name.lower().endswith(".bin"):
            os.replace(os.path.join(tmp, name), os.path.join(out_dir, name))
    os.replace(tmp_out, dst)


def _write_report(path, report):
    if not path:
        return
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
        json.dump(report, f, indent=2, sort_keys=True)


def main_single(argv) -> int:
    p = single_parser()
    try:
        args = p.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    if args.skip_existing and os.path.exists(args.output):
        print(f"atlas_defrag: skipped, {args.output} exists")
        return 0
    try:
        report = run_one(args)
    except Exception as exc:  # every failure: reason on stderr, exit 1
        msg = str(exc) if isinstance(exc, BatchError) or type(exc).__name__ == "DefragError" \
            else f"{type(exc).__name__}: {exc}"
        print(f"atlas_defrag: error: {args.input}: {msg}", file=sys.stderr)
        _write_report(args.report, {"input": os.path.abspath(args.input),
                                    "output": os.path.abspath(args.output),
                                    "status": "error", "error": msg})
        return 1
    _write_report(args.report, report)
    for w in report["warnings"] + [w for o in report["objects"] for w in o.get("warnings", [])]:
        print(f"atlas_defrag: warning: {w}", file=sys.stderr)
    for o in report["objects"]:
        print(f"atlas_defrag: {o['object']}: charts {o.get('charts_before')} -> {o.get('charts_after')}, "
              f"seam {o.get('seam_before', 0):.4g} -> {o.get('seam_after', 0):.4g}")
    print(f"atlas_defrag: wrote {args.output} in {report['seconds']['total']:.1f} s")
    return 0


# --------------------------------------------------------------------------- many models
def _expand(inputs):
    files = []
    for item in inputs:
        if os.path.isdir(item):
            for name in sorted(os.listdir(item)):
                if name.lower().endswith(INPUT_EXTS):
                    files.append(os.path.join(item, name))
        else:
            files.append(item)
    return files


def _blender_exe(arg):
    if arg:
        return arg
    if os.environ.get("BLENDER"):
        return os.environ["BLENDER"]
    try:
        import bpy
        if bpy.app.binary_path and os.path.basename(bpy.app.binary_path).startswith("blender"):
            return bpy.app.binary_path
    except ImportError:
        pass
    return "blender"


def main_multi(argv) -> int:
    p = multi_parser()
    try:
        args = p.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    files = _expand(args.inputs)
    if not files:
        print("atlas_defrag: error: no input models", file=sys.stderr)
        return 2
    os.makedirs(args.out_dir, exist_ok=True)
    command = [_blender_exe(args.blender), "--background", "--factory-startup", "--python-exit-code", "1",
               "--python", os.path.abspath(__file__), "--"]
    passthrough = _passthrough(args)
    jobs = _output_names(files, args.out_dir, args.format)
    failed = 0
    with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        for f, out, status, err in pool.map(lambda job: _run_one_blender(command, passthrough, *job), jobs):
            print(f"atlas_defrag: {status}: {f} -> {out}" + (f"\n  {err}" if err else ""),
                  file=sys.stderr if status == "failed" else sys.stdout)
            failed += status == "failed"
    print(f"atlas_defrag: {len(jobs) - failed} done, {failed} failed")
    return 1 if failed else 0


def _passthrough(args) -> list:
    """The single-model arguments that repeat the options given here."""
    out = []
    for opt in [o.name for o in _schema().SCHEMA] + ["uv_map", "texture"]:
        value = getattr(args, opt)
        if value is not None:
            out += ["--" + opt.replace("_", "-"), str(value)]
    if args.keep_source_uv:
        out.append("--keep-source-uv")
    return out


def _output_names(files, out_dir: str, fmt: str) -> list:
    """(input, output, report) per file; equal stems get _2, _3, ..."""
    stems = {}
    jobs = []
    for f in files:
        stem = os.path.splitext(os.path.basename(f))[0]
        stems[stem] = stems.get(stem, 0) + 1
        if stems[stem] > 1:
            stem = f"{stem}_{stems[stem]}"
        jobs.append((f, os.path.join(out_dir, f"{stem}.{fmt}"), os.path.join(out_dir, f"{stem}.report.json")))
    return jobs


def _run_one_blender(command, passthrough, f, out, rep):
    """(input, output, status, error line): one Blender process for one model."""
    if os.path.exists(out):
        return f, out, "skipped", ""
    proc = subprocess.run(command + [f, out, "--report", rep] + passthrough,
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if proc.returncode == 0:
        return f, out, "ok", ""
    err = [ln for ln in proc.stderr.splitlines() if "atlas_defrag: error" in ln]
    return f, out, "failed", (err[-1] if err else proc.stderr.strip()[-500:])


def main(argv=None) -> int:
    argv = _script_argv(argv)
    if "--out-dir" in argv or any(a.startswith("--out-dir=") for a in argv):
        return main_multi(argv)
    return main_single(argv)


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    if code:
        sys.exit(code)
