# SPDX-License-Identifier: MIT
"""Batch entry: defragments one model per Blender process.

One model (inside Blender)::

    blender --background --factory-startup --python-exit-code 1 \\
        --python .../atlas_defrag/batch.py -- IN OUT [options] [--report report.json]

IN is .obj, .gltf, .glb or .ply; OUT is .obj (writes OBJ + MTL + PNG beside it)
or .glb / .gltf. The exit code is 0 on success (or when skipped), 1 on failure
with the reason on stderr (an output that would replace an input included),
2 on arguments the parser refuses (an unknown option, a format it cannot write).

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
import py_compile
import re
import shutil
import signal
import stat
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.parse
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
    g.add_argument("--uv-map", default=None,
                   help="UV map to defragment (default: the active one, or the one the image maps read if they "
                        "read none through it)")
    g.add_argument("--texture", default=None,
                   help="image to use for meshes without an image texture (e.g. PLY)")
    g.add_argument("--keep-source-uv", action="store_true",
                   help="keep the original UV map in the output (as a second UV set)")
    g.add_argument("--skip-existing", action="store_true", help="do nothing if OUT exists")
    g.add_argument("--image-format", choices=IMAGE_FORMATS, default="auto",
                   help="glTF outputs: the format Blender's glTF exporter stores the images in (auto: as the "
                        "add-on writes them, PNG, lossless; jpeg: a fraction of the size, lossy, images with "
                        "alpha stay PNG; webp: Blender 4.0 and later)")
    g.add_argument("--image-quality", type=_quality, default=90,
                   help="1-100, for jpeg and webp where Blender's exporter takes a quality (4.0 and later; "
                        "Blender 3.x writes 90) (default 90)")


IMAGE_FORMATS = ("auto", "jpeg", "webp")


def _quality(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= 100:
        raise argparse.ArgumentTypeError(f"--image-quality must be an integer 1..100, not {text!r}")
    return value


def single_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="batch.py", description="Defragment the texture atlas of one model.",
                                epilog="Many models, one Blender each: python3 batch.py --out-dir OUT_DIR "
                                       "IN... [options] (--out-dir DIR --help says more).")
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
    """The objects an importer made of path; BatchError naming what failed."""
    import bpy
    before = set(bpy.data.objects)
    try:
        _run_importer(path)
    except RuntimeError as exc:
        error = _operator_error(exc)
        if re.match(r"^\w+(Error|Exception):", error) and not _file_system_error(error):  # Python's own words
            error += " (the importer broke on the file: it may break its format's specification, or use " \
                     "what this Blender's importer cannot read)"
        raise BatchError(f"Blender's importer failed: {error}") from exc
    new = [o for o in bpy.data.objects if o not in before]
    if not any(o.type == "MESH" for o in new):
        raise BatchError(f"no mesh imported from {path}")
    return new


def _file_system_error(error: str) -> bool:
    """Whether an error line names one of Python's OSErrors (a file the importer could not read)."""
    import builtins
    kind = getattr(builtins, error.split(":", 1)[0], None)
    return isinstance(kind, type) and issubclass(kind, OSError)


def _operator_error(exc: RuntimeError) -> str:
    """The error an import or export operator raised, without the traceback
    and the operator's location that Blender wraps it in."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip() and not ln.startswith("Location:")]
    errors = [ln for ln in lines if re.match(r"^([\w.]+(Error|Exception|error)|Error):", ln)
              and not ln.startswith("Error: Python: Traceback")]
    return (errors or lines or [repr(exc)])[-1]


def _run_importer(path: str) -> None:
    import bpy
    ext = os.path.splitext(path)[1].lower()
    if ext == ".obj":
        if _has_op(bpy.ops.wm, "obj_import"):
            bpy.ops.wm.obj_import(filepath=path)
        else:
            bpy.ops.import_scene.obj(filepath=path)
    elif ext in (".gltf", ".glb"):
        _numpy_bool_alias()
        bpy.ops.import_scene.gltf(filepath=path)
    elif ext == ".ply":  # Blender's importers drop per-face UVs (see ply_import)
        try:
            _, missing, notes = _package().ply_import.import_ply(path)
        except (OSError, ValueError, MemoryError) as exc:
            raise BatchError(f"cannot read {path}: {str(exc) or 'out of memory'}") from exc
        if missing:
            print(f"atlas_defrag: warning: texture files the PLY names are missing: {', '.join(missing)}",
                  file=sys.stderr)
        for note in notes:
            print(f"atlas_defrag: warning: {note}", file=sys.stderr)
    else:
        raise BatchError(f"unsupported input format '{ext}' (use {', '.join(INPUT_EXTS)})")


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


def _nodes_feeding_outputs(tree) -> set:
    """Names of the nodes from which links lead to a material output: the
    job leaves the old image nodes in the material, unlinked, and what they
    name no longer shows."""
    return {n.name for n in _upstream([n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"])}


def _upstream(starts, stop=lambda node: False) -> list:
    """starts and the nodes from which links lead to them, each once, in the
    order a depth-first walk meets them; the walk goes on past no node that
    stop holds for."""
    seen, stack, found = set(), list(starts), []
    while stack:
        node = stack.pop()
        if node.name in seen:
            continue
        seen.add(node.name)
        found.append(node)
        if not stop(node):
            stack += [link.from_node for socket in node.inputs for link in socket.links]
    return found


def _drop_source_uv(obj, name: str, report: dict) -> None:
    me = obj.data
    layer = me.uv_layers.get(name)
    if layer is None:
        return
    still_used = []
    for slot in obj.material_slots:
        mat = slot.material
        if mat and mat.node_tree:  # nodes the material still renders with that name the removed map
            rendered = _nodes_feeding_outputs(mat.node_tree)
            for n in mat.node_tree.nodes:
                if getattr(n, "uv_map", None) == name and n.name in rendered:
                    still_used.append(f"{mat.name}/{n.name}")
    me.uv_layers.remove(layer)
    if still_used:
        report.setdefault("warnings", []).append(
            "source UV map removed although these nodes named it: " + ", ".join(still_used))


def export_model(path: str, objects, image_format: str = "auto", quality: int = 90) -> None:
    """Writes objects to path with Blender's exporter; BatchError naming what failed."""
    try:
        _run_exporter(path, objects, image_format, quality)
    except RuntimeError as exc:  # a full disk, say: the operator raises with its traceback inside
        raise BatchError(f"Blender's exporter failed: {_operator_error(exc)}") from exc


def _run_exporter(path: str, objects, image_format: str, quality: int) -> None:
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
        if ext == ".gltf":
            _allow_embedded_gltf()
        kw = dict(filepath=path, export_format="GLB" if ext == ".glb" else "GLTF_EMBEDDED",
                  use_selection=True, export_normals=not _shaded_flat(objects),
                  export_image_format=_exporter_image_format(image_format),
                  export_image_quality=quality, export_jpeg_quality=quality)
        known = _operator_properties(bpy.ops.export_scene.gltf)
        kw = {k: v for k, v in kw.items() if k in known or k in ("filepath", "export_format")}
        bpy.ops.export_scene.gltf(**kw)
    else:
        raise BatchError(f"unsupported output format '{ext}' (use {', '.join(OUTPUT_EXTS)})")


def _exporter_image_format(image_format: str) -> str:
    """The glTF exporter's value for --image-format; BatchError when this
    Blender's exporter does not offer it (WebP before Blender 4.0)."""
    import bpy
    value = image_format.upper()
    offered = bpy.ops.export_scene.gltf.get_rna_type().properties["export_image_format"].enum_items.keys()
    if value not in offered:
        raise BatchError(f"--image-format {image_format}: this Blender's glTF exporter offers "
                         f"{', '.join(v.lower() for v in offered if v != 'NONE')} only")
    return value


def _shaded_flat(objects) -> bool:
    """True when every object with geometry is a mesh whose faces all shade flat (none
    smooth, no custom normals). glTF clients must then compute flat normals
    themselves (glTF 2.0, 3.7.2.1), so writing none looks the same, and the
    corners of a face no longer differ by normal: scans without normals (as
    Meshroom writes them) export fewer vertices, faster."""
    import numpy as np
    meshes = [o for o in objects if o.type == "MESH"]
    if not meshes or any(o.type in ("CURVE", "SURFACE", "FONT", "META") for o in objects):
        return False
    for o in meshes:
        me = o.data
        smooth = np.zeros(len(me.polygons), dtype=bool)
        me.polygons.foreach_get("use_smooth", smooth)
        if me.has_custom_normals or smooth.any():
            return False
    return True


def _allow_embedded_gltf() -> None:
    """Blender 4.2 and later offer the glTF format with embedded data only
    when the glTF add-on's preference allows it."""
    import bpy
    addon = bpy.context.preferences.addons.get("io_scene_gltf2")
    if addon is not None and hasattr(addon.preferences, "allow_embedded_format"):
        addon.preferences.allow_embedded_format = True


def _operator_properties(op) -> set:
    return {p.identifier for p in op.get_rna_type().properties}


def run_one(args, cancel=None) -> dict:
    """Imports args.input, defragments every textured mesh, exports args.output.

    Everything is written into a scratch folder beside the output, checked,
    then moved into place, the model file last: a failed or cancelled run
    leaves no file behind, and an existing OUT always means a finished run."""
    pkg = _package()
    t0 = time.perf_counter()
    src, dst = os.path.abspath(args.input), os.path.abspath(args.output)
    _refuse_folders(_model_files(dst))
    if not dst.lower().endswith(".obj"):
        _exporter_image_format(args.image_format)  # before the work: WebP needs Blender 4.0
    inputs, faces_in_file = _input_files(src)
    objects = _import_input(src, dst, inputs)
    inputs |= _input_files_of_scene()  # an OBJ's textures, found through its MTL
    _refuse_overwriting(inputs, _model_files(dst))
    libraries = _libraries_named_by(dst)  # the earlier output's, read once
    _refuse_foreign_library(dst, libraries)
    owned = _images_named_by(dst, libraries)
    written_before = _written_by(dst) if dst.lower().endswith(".obj") else set()
    t_import = time.perf_counter() - t0
    meshes = [o for o in objects if o.type == "MESH"]
    if args.texture:
        _give_missing_textures(pkg, meshes, os.path.abspath(args.texture))
    out_dir = os.path.dirname(dst) or "."
    os.makedirs(out_dir, exist_ok=True)
    report = {"input": src, "output": dst, "objects": [], "warnings": _interrupted_runs(dst)}
    report["warnings"] += _faces_the_import_dropped(src, faces_in_file, objects)
    scenes = _gltf_scene_count(src) if src.lower().endswith((".gltf", ".glb")) else 0
    if scenes > 1:
        report["warnings"].append(f"{os.path.basename(src)} holds {scenes} scenes: Blender's importer reads "
                                  "the nodes of all of them, and the output holds them in one")
    if args.keep_source_uv and dst.lower().endswith(".obj"):
        report["warnings"].append("--keep-source-uv: an OBJ holds one UV map, the new one")
    tmp = tempfile.mkdtemp(prefix=_SCRATCH_PREFIX, dir=out_dir)
    keep_scratch = False
    try:
        _defragment_meshes(pkg, args, meshes, tmp, report, cancel)
        copied = {}
        if dst.lower().endswith(".obj"):
            report["warnings"] += _base_colours_wired_straight(objects)
            copied = _bring_input_maps(objects, tmp, out_dir)
        _name_images_after(dst, tmp, owned)
        t_export = time.perf_counter()
        unnamed = _export_and_move(objects, tmp, dst, inputs | _input_files_of_scene(),  # --texture's too
                                   lambda: _stop_if_cancelled(pkg, cancel), owned | libraries,
                                   dict(image_format=args.image_format, quality=args.image_quality), copied,
                                   written_before)
        if unnamed:
            report["warnings"].append(
                f"{', '.join(unnamed)} written beside {os.path.basename(dst)}, but its materials do not name "
                "them: Blender's OBJ exporter writes only maps wired straight into the shader")
    except PreviousFilesKept:
        keep_scratch = True
        raise
    finally:
        if not keep_scratch:
            shutil.rmtree(tmp, ignore_errors=True)
    report["seconds"] = {"import": t_import, "export": time.perf_counter() - t_export,
                         "total": time.perf_counter() - t0}
    report["status"] = "ok"
    return report


def _obj_face_lines(data: bytes) -> int:
    """The `f` lines of an OBJ file's bytes."""
    return data.count(b"\nf ") + data.startswith(b"f ")


def _faces_the_import_dropped(src: str, in_file, objects) -> list:
    """A warning when Blender's OBJ importer made fewer faces than the file
    has (in_file: its `f` lines, None unless an OBJ): it skips a face naming a
    vertex the file lacks (printing only that it did) and drops repeated or
    degenerate ones, and the output lacks them all."""
    if in_file is None:
        return []
    made = sum(len(o.data.polygons) for o in objects if o.type == "MESH")
    if made >= in_file:
        return []
    return [f"Blender's OBJ importer made {made} of the {in_file} faces of {os.path.basename(src)}: it skips "
            "faces naming vertices the file lacks and drops repeated or degenerate ones; the output lacks them too"]


_SCRATCH_PREFIX = ".atlas_defrag_"
_SET_ASIDE_PREFIX = ".previous_"


def _scratch_folders(folder: str) -> list:
    """The scratch folders runs made in folder (none if it cannot be read)."""
    try:
        return sorted(e.path for e in os.scandir(folder) if e.name.startswith(_SCRATCH_PREFIX) and e.is_dir())
    except OSError:
        return []


def _set_aside_copies(dst: str) -> list:
    """The earlier dst that runs killed while moving their files in set aside
    in their scratch folders, newest first."""
    name = _SET_ASIDE_PREFIX + os.path.basename(dst)
    copies = [os.path.join(f, name) for f in _scratch_folders(os.path.dirname(dst) or ".")]
    return sorted((c for c in copies if os.path.isfile(c)), key=os.path.getmtime, reverse=True)


def _interrupted_runs(dst: str) -> list:
    """Warnings naming the scratch folders that hold an earlier dst set aside
    by a run that was killed while moving its files in (or could not put
    them back): left as they are, for the user. Runs into the same folder
    for other models are not named."""
    warnings = []
    for copy in _set_aside_copies(dst):
        folder = os.path.dirname(copy)
        try:
            kept = sorted(n[len(_SET_ASIDE_PREFIX):] for n in os.listdir(folder) if n.startswith(_SET_ASIDE_PREFIX))
        except OSError:
            continue
        warnings.append(f"{folder} holds files of an earlier output that an interrupted run set aside "
                        f"({', '.join(kept)}): left as they are")
    return warnings


def _real(path: str) -> str:
    return os.path.normcase(os.path.realpath(path))


def _model_files(dst: str) -> list:
    """The files the export writes besides images: the model and, for OBJ,
    its MTL (after it: a refusal names the model first)."""
    return [dst] + ([_mtl_beside(dst)] if dst.lower().endswith(".obj") else [])


def _mtl_beside(obj: str) -> str:
    """The MTL of an OBJ's own name: the one Blender's exporter writes, and its importer reads too."""
    return os.path.splitext(obj)[0] + ".mtl"


def _refuse_folders(paths) -> None:
    """BatchError when a path the output takes is a folder: the run would
    set it aside with the earlier output's files and remove it."""
    for path in sorted(paths):
        if os.path.isdir(path):
            raise BatchError(f"{path} is a folder: choose another output path")


def _input_files(src: str) -> tuple:
    """(src and the files it names that the import reads: an OBJ's MTL
    libraries (and the MTL of its own name, which Blender's importer reads
    too), a glTF's buffers and images; the `f` lines of an OBJ, read from
    the same bytes, else None)."""
    files, faces = {src}, None
    folder = os.path.dirname(src)
    try:
        if src.lower().endswith(".obj"):
            files.add(_mtl_beside(src))
            with open(src, "rb") as f:
                data = f.read()
            faces = _obj_face_lines(data)
            for line in _lines_starting(data, b"mtllib"):
                # Several libraries, or one whose name holds spaces (quoted or not): each reading is an input.
                names = line.decode("utf-8", "replace").split()[1:] + [_rest_of(line)]
                files.update(os.path.join(folder, n.strip('"')) for n in names if n.strip('"'))
        elif src.lower().endswith(".gltf"):
            with open(src, "r", encoding="utf-8") as f:
                gltf = json.load(f)
            for item in gltf.get("buffers", []) + gltf.get("images", []):
                uri = item.get("uri", "")
                if uri and not uri.startswith("data:"):
                    files.add(os.path.join(folder, urllib.parse.unquote(uri)))
    except (OSError, ValueError, TypeError, AttributeError):
        pass  # the importer reports what it cannot read
    return files, faces


def _gltf_scene_count(src: str) -> int:
    """How many scenes a .gltf or .glb file lists (0 when unreadable: the importer says why)."""
    try:
        with open(src, "rb") as f:
            head = f.read(20)
            data = f.read(struct.unpack_from("<I", head, 12)[0]) if head[:4] == b"glTF" else head + f.read()
        scenes = json.loads(data).get("scenes", [])
    except (OSError, ValueError, AttributeError, struct.error, RecursionError):
        return 0
    return len(scenes) if isinstance(scenes, list) else 0


def _input_files_of_scene() -> set:
    """The image files the imported materials read."""
    import bpy
    return {bpy.path.abspath(img.filepath) for img in bpy.data.images
            if img.source == "FILE" and img.filepath}


def _refuse_overwriting(inputs: set, outputs) -> None:
    """BatchError when an output would replace an input file (model, MTL,
    texture; see _file_among)."""
    for out in outputs:
        clash = _file_among(out, inputs)
        if clash:
            raise BatchError(f"the output would overwrite the input file {clash}: "
                             "choose another output path or folder")


def _file_among(path: str, files):
    """The one of files that path would overwrite: the same path, or the same
    file by another name (a hard link, or other letter case where the file
    system ignores it); None if none."""
    identity = _identity(path)
    return next((f for f in sorted(files)
                 if _real(f) == _real(path) or identity is not None and _identity(f) == identity), None)


def _refuse_foreign_library(dst: str, libraries: set) -> None:
    """BatchError when the MTL an OBJ output would write exists and is not
    one of libraries, the earlier output's at dst (_libraries_named_by): it
    is another model's, say."""
    mtl = _mtl_beside(dst)
    if dst.lower().endswith(".obj") and os.path.lexists(mtl) and os.path.basename(mtl) not in libraries:
        raise BatchError(f"{mtl} exists and is not the material library of {dst} (another model's?): "
                         "choose another output name")


def _identity(path: str):
    """(device, inode) of an existing file, else None."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return None
    return st.st_dev, st.st_ino


def _name_images_after(dst: str, folder: str, owned: set) -> None:
    """Renames the images saved in folder to '<stem>_<name>' after the model
    dst (and the bpy images pointing at them), so that models written into
    one folder never share an image file: every Meshroom scan names its
    texture texture_1001.png. A name taken in dst's folder by a file that
    dst's own material library does not name (owned: those it does, from
    _images_named_by; another model's, whose stem and image name join the
    same way) gets a number."""
    import bpy
    stem = os.path.splitext(os.path.basename(dst))[0]
    out_dir = os.path.dirname(dst)
    real = _real(folder)
    for img in bpy.data.images:
        path = bpy.path.abspath(img.filepath) if img.filepath else ""
        if not path or _real(os.path.dirname(path)) != real:
            continue
        name = os.path.basename(path)
        new, k = f"{stem}_{name}", 1
        while os.path.exists(os.path.join(folder, new)) or (
                os.path.exists(os.path.join(out_dir, new)) and new not in owned):
            base, ext = os.path.splitext(name)
            new = f"{stem}_{base}.{k:03d}{ext}"
            k += 1
        os.replace(path, os.path.join(folder, new))
        img.filepath = os.path.join(folder, new)


def _libraries_named_by(model: str) -> set:
    """The material libraries an existing OBJ model names (a previous run's
    output, which this one replaces), or where a run was killed after setting
    it aside, its copy in that run's scratch folder."""
    if not model.lower().endswith(".obj"):
        return set()
    source = model if os.path.isfile(model) else next(iter(_set_aside_copies(model)), None)
    if source is None:
        return set()
    with open(source, "rb") as f:
        return {_rest_of(ln) for ln in _lines_starting(f.read(), b"mtllib")} - {""}


def _images_named_by(model: str, libraries: set) -> set:
    """The files that libraries (model's, from _libraries_named_by) name, in
    map statements or in the note of the images written unnamed (_note_unnamed)."""
    folder = os.path.dirname(model)
    named = set()
    for lib in libraries:
        try:
            with open(os.path.join(folder, lib), "rb") as f:
                data = f.read()
        except OSError:
            continue
        named |= _map_files(data) | {ln[len(_UNNAMED_NOTE):].strip().decode("utf-8", "replace")
                                     for ln in _lines_starting(data, b"#") if ln.startswith(_UNNAMED_NOTE)}
    return named


# The MTL's comment naming an image written beside an OBJ that no statement
# names (an occlusion map): a rerun then knows the file for its own.
_UNNAMED_NOTE = b"# written beside this model by Atlas Defrag, named by no statement:"


# The MTL's comment naming every image a run wrote beside the OBJ: a rerun
# into the same OBJ takes away those it does not write again, and never a
# file that a MTL it did not write names.
_WRITTEN_NOTE = b"# written beside this model by Atlas Defrag:"


def _note_written(mtl: str, images: list) -> None:
    """Appends the _WRITTEN_NOTE of each of images to the MTL."""
    with open(mtl, "ab") as f:
        f.write(b"".join(_WRITTEN_NOTE + b" " + name.encode("utf-8") + b"\n" for name in images))


def _written_by(dst: str) -> set:
    """The images the _WRITTEN_NOTE of the MTL beside the OBJ dst names."""
    try:
        with open(_mtl_beside(dst), "rb") as f:
            data = f.read()
    except OSError:
        return set()
    return {ln[len(_WRITTEN_NOTE):].strip().decode("utf-8", "replace")
            for ln in _lines_starting(data, b"#") if ln.startswith(_WRITTEN_NOTE)}


def _note_unnamed(mtl: str, images: list) -> None:
    """Appends the _UNNAMED_NOTE of each of images to the MTL."""
    with open(mtl, "ab") as f:
        f.write(b"".join(_UNNAMED_NOTE + b" " + name.encode("utf-8") + b"\n" for name in images))


def _format_problem(src: str, dst: str) -> str:
    """Why src cannot be read or dst written, going by their extensions ('' if they can)."""
    for kind, path, exts in (("input", src, INPUT_EXTS), ("output", dst, OUTPUT_EXTS)):
        ext = os.path.splitext(path)[1].lower()
        if ext not in exts:
            return f"unsupported {kind} format '{ext}' (use {', '.join(exts)})"
    return ""


def _import_input(src: str, dst: str, inputs: set):
    """The objects of src, in an empty scene; refuses what cannot be written,
    and files to read (inputs, from _input_files) that cannot be read."""
    import bpy
    if not os.path.isfile(src):
        raise BatchError(f"input not found: {src}")
    problem = _format_problem(src, dst)
    if problem:
        raise BatchError(problem)
    _refuse_special_files(inputs)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return import_model(src)


def _refuse_special_files(inputs: set) -> None:
    """BatchError when one of inputs, or an image their MTL files name, is a
    FIFO, a device or a socket (Blender's importers would wait on it for ever
    or read it without end), or an image whose header claims what it cannot
    be decoded safely into (image_headers.size_problem): some of Blender's
    decoders run during the import."""
    headers = importlib.import_module(_package().__name__ + ".image_headers")
    files = set(inputs)
    for mtl in [f for f in inputs if f.lower().endswith(".mtl")]:
        if _special(mtl):
            break  # refused below, unread
        try:
            with open(mtl, "rb") as f:
                files |= {os.path.join(os.path.dirname(mtl), name) for name in _map_files(f.read())}
        except OSError:
            continue  # missing: the importer does without it
    for path in sorted(files):
        if _special(path):
            raise BatchError(f"{path} is not a regular file (a FIFO, device or socket): "
                             "the import would wait on it or read it without end")
        if path.lower().endswith(_NO_IMAGE_EXTS):
            continue
        try:
            with open(path, "rb") as f:
                claim = headers.claimed_size(f, path)
                problem = headers.size_problem(claim, os.fstat(f.fileno()).st_size) if claim else ""
        except OSError:
            continue
        if problem:
            raise BatchError(f"the image {path} claims {problem}: scale it down or repair it first")


# The files an import reads that are no images: their bytes may start as an image's signature.
_NO_IMAGE_EXTS = (".obj", ".mtl", ".gltf", ".glb", ".bin", ".ply")


def _special(path: str) -> bool:
    """Whether path exists and is neither a regular file nor a folder."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def _give_missing_textures(pkg, meshes, texture: str) -> None:
    """A material with the image on Base Color, for meshes with UVs that have none."""
    for o in meshes:
        if not _has_image_texture(pkg, o) and len(o.data.uv_layers):
            o.data.materials.clear()
            o.data.materials.append(pkg.ply_import.image_material(texture))


def _defragment_meshes(pkg, args, meshes, image_dir: str, report: dict, cancel=None) -> None:
    """Each mesh once (linked duplicates share it); its report into report['objects']."""
    done_meshes = set()
    errors = []
    api = importlib.import_module(pkg.__name__ + ".api")
    shared = api.shared_materials(meshes)
    options = {o.name: getattr(args, o.name) for o in _schema().SCHEMA}
    for o in meshes:
        if o.data.name in done_meshes:
            continue
        # The source map is removed after the run: when it is the mesh's only
        # map, the new one ends up first without being moved there.
        only_map_goes = not args.keep_source_uv and len(o.data.uv_layers) == 1
        try:
            r = pkg.defragment(
                o, cancel=cancel, wait_in_main_thread=True, uv_map=args.uv_map, storage="SAVE", image_dir=image_dir,
                duplicate_materials=api.uses_any(o, shared), new_map_first=not only_map_goes,
                **options)
        except pkg.DefragCancelled:
            raise
        except pkg.DefragError as exc:
            errors.append(f"{o.name}: {exc}")
            continue
        done_meshes.add(o.data.name)
        if not args.keep_source_uv:
            _drop_source_uv(o, r["source_uv_map"], r)
            r["new_map_first"] = o.data.uv_layers[0].name == r["uv_map"]  # as the mesh is left
        report["objects"].append(pkg.api.plain(r))
    if not report["objects"]:
        raise BatchError("nothing to defragment: " + _listed(errors or ["no mesh"]))
    report["warnings"].extend(errors)


def _listed(reasons, most: int = 3) -> str:
    """The first few reasons, then how many more: a model of hundreds of
    meshes without UVs would otherwise fill the terminal with one line."""
    more = len(reasons) - most
    return "; ".join(reasons[:most]) + (f"; and {more} more meshes" if more > 0 else "")


def _stop_if_cancelled(pkg, cancel) -> None:
    if cancel is not None and cancel.cancelled:
        raise pkg.DefragCancelled("cancelled")


def _export_and_move(objects, tmp: str, dst: str, inputs: set, before_moving, replaceable: set,
                     export_images=None, copied=None, written_before=frozenset()) -> list:
    """Exports into tmp, checks every file there, calls before_moving (which
    may raise), then moves them beside dst: images next to an OBJ (a glTF
    carries them), the model file last. Images and the MTL may replace only
    the files named in replaceable: the earlier output's at dst (its
    libraries and their images). Returns the images moved beside an OBJ that
    its materials do not name. export_images: export_model's image_format and
    quality; copied: what _bring_input_maps copied into tmp; written_before:
    the images the earlier run into dst wrote (_written_by), taken away once
    the new model is in place unless written again."""
    export_images = export_images or {}
    out_dir = os.path.dirname(dst) or "."
    tmp_out = os.path.join(tmp, os.path.basename(dst))
    export_model(tmp_out, objects, **export_images)
    is_obj = dst.lower().endswith(".obj")
    copies = _copies_named(tmp, copied) if is_obj and copied else {}
    moving = [name for name in sorted(os.listdir(tmp))
              if name != os.path.basename(dst) and (is_obj or name.lower().endswith(".bin"))]
    # Each check reads the materials for one kind of output: the copies of
    # input maps in tmp would count as rebuilt ones.
    unnamed = _verify_outputs(tmp, os.path.basename(dst), moving,
                              sum(len(o.data.polygons) for o in objects if o.type == "MESH"),
                              _base_colour_files(objects) if is_obj else frozenset(), copies,
                              frozenset() if is_obj else _rebuilt_materials(objects, tmp))
    _refuse_overwriting(inputs, [os.path.join(out_dir, name) for name in moving])
    if unnamed:
        _note_unnamed(_mtl_beside(tmp_out), unnamed)
    if is_obj:
        _note_written(_mtl_beside(tmp_out), [n for n in moving if not n.lower().endswith(".mtl")])
    before_moving()
    moved, kept = [], []  # kept: (the previous run's file, set aside in tmp; where it was)

    def set_aside(target: str) -> None:
        if os.path.isdir(target) and not os.path.islink(target):
            raise BatchError(f"{target} is a folder: nothing was replaced; choose another output path")
        if os.path.lexists(target):
            previous = os.path.join(tmp, _SET_ASIDE_PREFIX + os.path.basename(target))
            os.replace(target, previous)
            kept.append((previous, target))

    try:
        # The earlier model goes first: a run killed midway leaves no model
        # beside images it does not match (_interrupted_runs names the rest).
        # A lone model file is replaced in one step instead.
        if moving:
            set_aside(dst)
        for name in moving:
            target = os.path.join(out_dir, name)
            if name in replaceable or name.lower().endswith(".bin"):
                set_aside(target)
                os.replace(os.path.join(tmp, name), target)
            else:
                _move_new(os.path.join(tmp, name), target)
            moved.append(target)
        os.replace(tmp_out, dst)
    except BaseException as exc:
        for path in moved:
            _remove_quietly(path)
        elsewhere = _restore(kept[::-1])  # the model goes back last
        if elsewhere:
            raise PreviousFilesKept(f"{exc}; the previous output's files could not all be put back: they are "
                                    f"kept as {', '.join(elsewhere)}") from exc
        raise
    if is_obj:
        _take_away_stale(dst, tmp, written_before - set(moving), inputs)
    return unnamed


def _take_away_stale(dst: str, tmp: str, names: set, inputs: set) -> None:
    """Moves into tmp (which goes with the run) the images that the earlier
    run into the OBJ dst wrote (its MTL's _WRITTEN_NOTE) and this one did
    not write again: pages beyond its own. Only plain names beside dst,
    regular files, none an input or named by the new MTL; a file that
    cannot be moved stays."""
    out_dir = os.path.dirname(dst) or "."
    for name in sorted(names - _images_named_by(dst, _libraries_named_by(dst))):
        target = os.path.join(out_dir, name)
        if os.path.basename(name) != name or not os.path.isfile(target) or os.path.islink(target) \
                or _file_among(target, inputs) is not None:
            continue
        try:
            os.replace(target, os.path.join(tmp, _SET_ASIDE_PREFIX + name))
        except OSError:
            pass


class PreviousFilesKept(BatchError):
    """A failed run could not put all of the previous run's files back: the
    scratch folder that may still hold them is left in place."""


def _restore(kept) -> list:
    """Puts the previous run's files back (the previous model stays whole).
    Returns where those that could not go back are: beside their place, or
    still in the scratch folder."""
    elsewhere = []
    for previous, target in kept:
        try:
            os.replace(previous, target)
        except OSError:
            beside = next((f"{target}.previous{k or ''}" for k in range(100)
                           if not os.path.lexists(f"{target}.previous{k or ''}")), previous)
            try:
                os.replace(previous, beside)  # a name no file has: nothing of the user's is replaced
                elsewhere.append(beside)
            except OSError:
                elsewhere.append(previous)
    return elsewhere


def _move_new(src: str, dst: str) -> None:
    """Moves src to dst, which must not exist: another model's run may have
    written that name into the folder since it was chosen (or a file the
    user keeps there)."""
    try:
        os.link(src, dst)
    except FileExistsError:
        raise BatchError(f"{dst} appeared while this model was written (another model's image?): "
                         "nothing was replaced; run this model again") from None
    except OSError:  # a file system without hard links
        if os.path.exists(dst):
            raise BatchError(f"{dst} appeared while this model was written: nothing was replaced") from None
        os.replace(src, dst)
        return
    os.remove(src)


_IMAGE_EXTENSIONS = {"PNG": ".png", "JPEG": ".jpg", "TARGA": ".tga", "TARGA_RAW": ".tga", "BMP": ".bmp",
                     "OPEN_EXR": ".exr", "TIFF": ".tif", "WEBP": ".webp", "HDR": ".hdr"}


def _bring_input_maps(objects, folder: str, out_dir: str) -> dict:
    """For an OBJ output: copies into folder (the scratch folder of the new
    images) the input images that the objects' materials still show
    (materials the job left unchanged: a texture transform, say), from their
    files or, packed in a GLB, from the bytes Blender holds, and points their
    Blender images at the copies. Blender's OBJ exporter names a map by its
    file name only, so the MTL must find it beside the OBJ: a packed image
    has no file to name, and a file of that name already beside the output
    may be another model's. Images whose file is in folder or out_dir stay.
    Returns {Blender image name: bytes its file holds}."""
    import bpy
    copied = {}
    for img in dict.fromkeys(img for m in _materials_of(objects) for img in _shown_images(m)):
        path = bpy.path.abspath(img.filepath, library=img.library) if img.filepath else ""
        here = path and os.path.isfile(path)
        if here and _real(os.path.dirname(path)) in (_real(folder), _real(out_dir)):
            continue
        if not here and img.packed_file is None:
            continue  # no pixels to bring: the MTL names the file the input named, as before
        name = os.path.basename(path) if path else bpy.path.clean_name(img.name) + _IMAGE_EXTENSIONS.get(
            img.file_format, ".png")
        target = _free_name(folder, name)
        if here:
            shutil.copyfile(path, target)
        else:
            with open(target, "wb") as f:
                f.write(img.packed_file.data)
        img.filepath_raw = target
        copied[img.name] = os.path.getsize(target)
    return copied


def _base_colours_wired_straight(objects) -> list:
    """For an OBJ output: an image that reaches a Principled BSDF's Base
    Color through other nodes (a Mix with a colour factor or vertex colours,
    as Blender's glTF importer builds them) is linked to it straight, so that
    Blender's OBJ exporter names it (map_Kd); what the nodes mixed in, which
    an MTL cannot hold, is dropped with a warning. Only the scene the batch
    imported changes. Returns the warnings."""
    warnings = []
    for mat in _materials_of(objects):
        tree = _package().compat.node_tree(mat)
        for bsdf in [n for n in tree.nodes if n.type == "BSDF_PRINCIPLED"] if tree else []:
            socket = bsdf.inputs["Base Color"]
            if not socket.is_linked or _through_reroutes(socket.links[0].from_node).type == "TEX_IMAGE":
                continue  # the exporter follows reroutes
            mixer = socket.links[0].from_node
            images = _upstream_images(mixer)
            if len(images) == 1:
                tree.links.new(images[0].outputs["Color"], socket)
                warnings.append(f"material '{mat.name}': the OBJ names its base colour image alone; what nodes "
                                f"mixed into it ({mixer.name} and before) has no MTL form")
    return warnings


def _through_reroutes(node):
    """The node a chain of Reroute nodes starting at node passes on."""
    while node.type == "REROUTE" and node.inputs[0].is_linked:
        node = node.inputs[0].links[0].from_node
    return node


def _upstream_images(node) -> list:
    """The image nodes (with an image) that feed node, directly or through others."""
    def image(n):
        return n.type == "TEX_IMAGE" and n.image is not None
    return [n for n in _upstream([node], stop=image) if image(n)]


def _materials_of(objects) -> list:
    """The materials in the objects' slots, each once."""
    return list(dict.fromkeys(slot.material for o in objects for slot in getattr(o, "material_slots", [])
                              if slot.material))


def _shown_images(material) -> list:
    """The images of the image nodes that feed the material's output."""
    tree = _package().compat.node_tree(material)
    if tree is None:
        return []
    shown = _nodes_feeding_outputs(tree)
    return [n.image for n in tree.nodes
            if n.name in shown and n.bl_idname == "ShaderNodeTexImage" and n.image is not None]


def _free_name(folder: str, name: str) -> str:
    """folder/name, or with a number before its extension when taken."""
    base, ext = os.path.splitext(name)
    target, k = os.path.join(folder, name), 1
    while os.path.lexists(target):
        target, k = os.path.join(folder, f"{base}.{k:03d}{ext}"), k + 1
    return target


def _copies_named(folder: str, copied: dict) -> dict:
    """{file in folder: bytes it must hold} of the copies _bring_input_maps
    made (copied, by Blender image) that the MTLs in folder name; those they
    do not name are removed (Blender's OBJ exporter writes only maps wired
    straight into the shader)."""
    import bpy
    named = set()
    for name in os.listdir(folder):
        if name.lower().endswith(".mtl"):
            with open(os.path.join(folder, name), "rb") as f:
                named |= _map_files(f.read())
    kept = {}
    for image_name, size in copied.items():
        path = bpy.path.abspath(bpy.data.images[image_name].filepath)
        if os.path.basename(path) in named:
            kept[os.path.basename(path)] = size
        else:
            _remove_quietly(path)
    return kept


def _require_gltf_images(path: str, written, rebuilt=frozenset()) -> None:
    """BatchError when the glTF at path holds no image although the job wrote
    some (written: their files), or gives a material the job rebuilt
    (rebuilt: their names) no texture: Blender's glTF exporter drops
    textures behind shader nodes it cannot export, and the model would come
    out without its new atlas."""
    if not written:
        return
    with open(path, "rb") as f:
        if path.lower().endswith(".glb"):  # the JSON chunk only: the binary one is the model's size
            head = f.read(20)
            data = f.read(struct.unpack_from("<I", head, 12)[0]) if len(head) == 20 else b"{}"
        else:
            data = f.read()
    gltf = json.loads(data)
    bare = sorted(m["name"] for m in gltf.get("materials", [])
                  if m.get("name") in rebuilt and not _names_a_texture(m))
    if not gltf.get("images") or bare:
        lost = f"the materials {', '.join(bare)} without a texture" if gltf.get("images") else \
            f"none of the new images ({', '.join(sorted(written))})"
        raise BatchError(
            f"Blender's glTF exporter wrote {lost}: the materials use shader nodes it cannot export (a "
            "specular-glossiness material, say), so the model would lose its texture; nothing was written. "
            "Write an OBJ instead, or wire the textures into a Principled BSDF")


def _names_a_texture(value) -> bool:
    """Whether glTF JSON (a material's) holds a texture reference anywhere:
    an object with an index."""
    if isinstance(value, dict):
        return "index" in value or any(_names_a_texture(v) for v in value.values())
    return isinstance(value, list) and any(_names_a_texture(v) for v in value)


def _rebuilt_materials(objects, folder: str) -> set:
    """The names of the objects' materials that show an image whose file is
    in folder: the ones the job rebuilt around its new images."""
    import bpy
    real = _real(folder)
    return {m.name for m in _materials_of(objects)
            if any(img.filepath and _real(os.path.dirname(bpy.path.abspath(img.filepath))) == real
                   for img in _shown_images(m))}


def _remove_quietly(path: str) -> None:
    try:
        os.remove(path)
    except OSError:
        pass


def _verify_outputs(folder: str, model: str, others, polygons: int, base_colours=frozenset(), copies=None,
                    rebuilt=frozenset()) -> list:
    """BatchError unless every written file is whole: exporters report success
    on a full disk and leave truncated or empty files; and unless a glTF
    holds images where the job wrote some and gives every material the job
    rebuilt a texture (_require_gltf_images). Returns the images written
    beside an OBJ that its materials do not name. base_colours: the files an
    OBJ's MTL must name (see _base_colour_files); copies: {file: bytes} of
    input images copied as they were, whole when all their bytes are there;
    rebuilt: the names of the materials the job rebuilt."""
    copies = copies or {}
    for name in [model] + list(others):
        path = os.path.join(folder, name)
        problem = _copy_problem(path, copies[name]) if name in copies else \
            _file_problem(path, polygons if name == model else None)
        if problem:
            raise BatchError(f"writing {name} failed ({problem}): is the disk full?")
    if not model.lower().endswith(".obj"):
        _require_gltf_images(os.path.join(folder, model),
                             [n for n in os.listdir(folder) if n.lower().endswith((".png", ".exr"))], rebuilt)
        return []
    return _verify_obj_references(folder, model, [n for n in others if not n.lower().endswith(".mtl")],
                                  base_colours)


def _base_colour_files(objects) -> set:
    """The image files wired straight into a Principled BSDF's Base Color in
    the objects' materials: Blender's OBJ exporter always names those in the
    MTL (map_Kd, by file name with path_mode STRIP)."""
    files = set()
    for mat in _materials_of(objects):
        tree = _package().compat.node_tree(mat)
        for link in tree.links if tree else []:
            image = getattr(link.from_node, "image", None)
            if link.to_node.type == "BSDF_PRINCIPLED" and link.to_socket.name == "Base Color" and \
                    link.from_node.type == "TEX_IMAGE" and image is not None and image.filepath:
                files.add(os.path.basename(image.filepath))
    return files


def _copy_problem(path: str, size: int) -> str:
    """What is wrong with a file copied as it was, or '' when all its bytes are there."""
    if not os.path.isfile(path):
        return "missing"
    written = os.path.getsize(path)
    return f"{written} of {size} bytes" if written != size else ""


def _file_problem(path: str, polygons) -> str:
    """What is wrong with one written file, or '' when it looks whole."""
    if not os.path.isfile(path):
        return "missing"
    if os.path.getsize(path) == 0:
        return "empty"
    ext = os.path.splitext(path)[1].lower()
    if ext in (".png", ".exr", ".glb"):  # binary files, whole when their ends are
        return _binary_file_problem(path, ext)
    with open(path, "rb") as f:
        data = f.read()
    if ext == ".gltf":
        try:
            json.loads(data)
        except ValueError:
            return "not complete JSON"
    if ext == ".mtl" and b"newmtl" not in data:
        return "no material in it"
    if ext == ".obj" and polygons is not None:
        faces = _obj_face_lines(data)
        if faces != polygons or not data.endswith(b"\n"):
            return f"{faces} of {polygons} faces"
    return ""


def _binary_file_problem(path: str, ext: str) -> str:
    """_file_problem of a PNG, EXR or GLB file, from its first and last bytes."""
    png_files = importlib.import_module(_package().__name__ + ".png_files")
    size = os.path.getsize(path)
    head, tail = png_files.file_ends(path, 12, png_files.TAIL_BYTES)
    if ext == ".png" and not (head.startswith(png_files.SIGNATURE) and png_files.ends_whole(tail)):
        return "not a complete PNG"
    if ext == ".exr" and not head.startswith(b"\x76\x2f\x31\x01"):
        return "not an OpenEXR file"
    if ext == ".glb" and (len(head) < 12 or head[:4] != b"glTF" or struct.unpack_from("<I", head, 8)[0] != size):
        return "shorter than its header says"
    return ""


def _verify_obj_references(folder: str, model: str, images, base_colours=frozenset()) -> list:
    """BatchError unless the OBJ's material libraries are there and whole:
    each ends with a line end, together they define every material the OBJ
    uses and name every file of base_colours (a cut-short MTL loses its last
    lines, and a material's maps come last in it). Returns the images
    written beside the OBJ that no MTL names: Blender's OBJ exporter writes
    only maps wired straight into the shader (not an occlusion map, nor one
    behind a Mix node). Names the MTL carries over from the input (even
    broken ones) are not checked."""
    with open(os.path.join(folder, model), "rb") as f:
        obj = f.read()
    used = {_rest_of(ln) for ln in _lines_starting(obj, b"usemtl")} - {""}  # "": an empty material slot
    defined, named = set(), set()
    for lib in (_rest_of(ln) for ln in _lines_starting(obj, b"mtllib")):
        lib_path = os.path.join(folder, lib)
        if not lib or not os.path.isfile(lib_path):
            raise BatchError(f"writing {model} failed: its material library {lib} is missing")
        with open(lib_path, "rb") as f:
            data = f.read()
        if not data.endswith(b"\n"):
            raise BatchError(f"writing {model} failed: its material library {lib} is cut short: is the disk full?")
        defined.update(_rest_of(ln) for ln in _lines_starting(data, b"newmtl"))
        named |= _map_files(data)
    undefined = sorted(used - defined)
    if undefined:
        raise BatchError(f"writing {model} failed: its material libraries do not define {', '.join(undefined)}: "
                         "is the disk full?")
    unnamed = sorted(set(base_colours) - named)
    if unnamed:
        raise BatchError(f"writing {model} failed: its material libraries do not name {', '.join(unnamed)}: "
                         "is the disk full?")
    return sorted(set(images) - named)


def _map_files(mtl: bytes) -> set:
    """The files the map statements of an MTL file's text name."""
    mtl_text = importlib.import_module(_package().__name__ + ".mtl_text")
    return {mtl_text.map_file(_rest_of(ln)) for statement in mtl_text.MAP_STATEMENTS
            for ln in _lines_starting(mtl, statement.encode())}


def _rest_of(line: bytes) -> str:
    """A statement's argument: the line after its first word, spaces inside kept."""
    parts = line.split(None, 1)
    return parts[1].strip().decode("utf-8", "replace") if len(parts) > 1 else ""


def _lines_starting(data: bytes, prefix: bytes) -> list:
    """The lines of data whose first word starts with prefix, without their
    line ends. bytes.find skips the millions of other lines of a large OBJ,
    which a loop over lines would take seconds to read."""
    lines = []
    at = data.find(prefix)
    while at != -1:
        start = data.rfind(b"\n", 0, at) + 1
        end = data.find(b"\n", at)
        end = len(data) if end == -1 else end
        if not data[start:at].strip():
            lines.append(data[at:end].rstrip(b"\r"))
        at = data.find(prefix, end)
    return lines


def _write_report(path, report):
    if not path:
        return
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    tmp = f"{path}.{os.getpid()}.tmp"
    f = open(tmp, "x")  # "x": never over a file of that name
    try:
        with f:
            json.dump(report, f, indent=2, sort_keys=True)
        os.replace(tmp, path)
    except BaseException:
        _remove_quietly(tmp)
        raise


def _report_path_problem(path, src: str, dst: str) -> str:
    """Why the report could not be written there, checked before the work
    ('' if it can): among others, onto the input or the output."""
    if not path:
        return ""
    path = os.path.abspath(path)
    if os.path.isdir(path):
        return f"--report {path} is a folder"
    other = _file_among(path, _input_files(os.path.abspath(src))[0] | set(_model_files(os.path.abspath(dst))))
    if other:
        return f"--report {path} would overwrite {other}"
    if os.path.lexists(path) and not _is_report(path):
        return f"--report {path} exists and is not a report of this entry (a texture?): it would be overwritten"
    folder = os.path.dirname(path)
    probe = folder
    while probe and not os.path.exists(probe):
        probe = os.path.dirname(probe)
    if not os.path.isdir(probe):
        return f"--report {path}: {probe} is not a folder"
    if not os.access(probe, os.W_OK | os.X_OK) or (os.path.exists(path) and not os.access(path, os.W_OK)):
        return f"--report {path} is not writable"
    return ""


def _is_report(path: str) -> bool:
    """Whether the file at path is a JSON report (an earlier run's, which a
    new one may replace)."""
    try:
        with open(path, "rb") as f:
            data = json.loads(f.read(1 << 20))
    except (OSError, ValueError):
        return False
    return isinstance(data, dict) and "status" in data


class _Interrupt:
    """SIGINT and SIGTERM (what timeout, kill, GNU parallel and job
    schedulers send) cancel the run's token instead of killing the process
    midway, which would leave its scratch folder behind. A signal before the
    token exists (Blender's start-up modules are still compiling, say) is
    kept and cancels it when attached. The handlers before are restored on exit."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.token, self.caught, self.previous = None, "", {}

    def __enter__(self):
        if threading.current_thread() is threading.main_thread():
            self.previous = {s: signal.signal(s, self._catch) for s in self.SIGNALS}
        return self

    def _catch(self, signum, _frame):
        self.caught = signal.Signals(signum).name
        if self.token is not None:
            self.token.cancel()

    def attach(self, token) -> None:
        self.token = token
        if self.caught:
            token.cancel()

    def __exit__(self, *exc):
        _restore_handlers(self.previous)
        return False


def _restore_handlers(previous: dict) -> None:
    """signal.signal(s, handler) for each, but one set outside Python (None: Blender's own), which stays ours."""
    for s, handler in previous.items():
        if handler is not None:
            signal.signal(s, handler)


EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it


def bytecode_cache_dir() -> str:
    """Where the batch entry keeps compiled Python: the user's own cache
    directory (LOCALAPPDATA on Windows, else XDG_CACHE_HOME or ~/.cache),
    never a shared one, whose files another user could have planted; '' when
    the user has no home to find it in (expanduser then leaves '~' as it is)."""
    home = os.path.expanduser("~")
    if os.name == "nt":
        base = os.environ.get("LOCALAPPDATA") or os.path.join(home, "AppData", "Local")
    else:
        base = os.environ.get("XDG_CACHE_HOME", "")
        if not os.path.isabs(base):  # the XDG spec ignores a relative path
            base = os.path.join(home, ".cache")
    return os.path.join(base, "atlas_defrag", "pycache") if os.path.isabs(base) else ""


def _writable_cache(path: str) -> bool:
    """Whether the cache folder exists (made private if it is new) and takes
    files: a compile whose write fails costs as much as one whose write
    succeeds, so a read-only cache would make every process slower."""
    try:
        os.makedirs(path, mode=0o700, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            return True
    except OSError:
        return False


def _cache_bytecode() -> None:
    """Blender turns Python's bytecode cache off (sys.dont_write_bytecode), and
    a Blender whose scripts ship without one (Debian's) compiles its start-up
    modules, the glTF add-on and this package again in every batch process:
    about a third of a second each, for every model of a collection. The cache
    goes to bytecode_cache_dir() (or to the PYTHONPYCACHEPREFIX Blender was
    started with), apart from the sources, so that read-only installs stay
    untouched. Blender's start-up reads it only when started with that
    variable (README, the many-models entry sets it); the modules it imported
    before this script ran are written here, once (a second or two on the
    first run). A folder that cannot be made or written to leaves the cache
    off, and so does a write that fails midway (a full disk)."""
    path = sys.pycache_prefix or bytecode_cache_dir()
    if not path or not _writable_cache(path):
        return
    sys.pycache_prefix = path
    sys.dont_write_bytecode = False
    for module in list(sys.modules.values()):
        source = getattr(module, "__file__", None)
        if source and source.endswith(".py") and not _bytecode_current(source):
            try:
                py_compile.compile(source, cfile=importlib.util.cache_from_source(source), quiet=2,
                                   invalidation_mode=py_compile.PycInvalidationMode.TIMESTAMP)
            except OSError:
                sys.dont_write_bytecode = True
                return


def _bytecode_current(source: str) -> bool:
    """Whether the cached bytecode of source is there and was compiled from it
    as it is now (the header Python checks: magic number, no flags, the
    source's mtime and size, PEP 552)."""
    try:
        with open(importlib.util.cache_from_source(source), "rb") as f:
            header = f.read(16)
        st = os.stat(source)
    except OSError:
        return False
    return header == importlib.util.MAGIC_NUMBER + struct.pack(
        "<III", 0, int(st.st_mtime) & 0xFFFFFFFF, st.st_size & 0xFFFFFFFF)


def _image_format_problem(image_format: str, output_ext: str) -> str:
    """Why --image-format cannot apply to an output of that extension ('' if it can)."""
    if image_format == "auto" or output_ext in (".glb", ".gltf"):
        return ""
    return f"--image-format {image_format} applies to glTF outputs: an OBJ's images are the PNG files beside it"


def main_single(argv) -> int:
    p = single_parser()
    try:
        args = _schema().parsed(p, argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    problem = _report_path_problem(args.report, args.input, args.output) or _format_problem(args.input, args.output)
    if problem:
        print(f"atlas_defrag: error: {problem}", file=sys.stderr)
        return 2
    problem = _image_format_problem(args.image_format, os.path.splitext(args.output)[1].lower())
    if problem:
        print(f"atlas_defrag: error: {problem}", file=sys.stderr)
        return 2
    if args.skip_existing and os.path.isfile(args.output):
        print(f"atlas_defrag: skipped, {args.output} exists")
        return 0
    with _Interrupt() as interrupt:
        return _run_single(args, interrupt)


def _run_single(args, interrupt: _Interrupt) -> int:
    """main_single's work once the arguments are checked, signals caught by interrupt."""
    try:
        _cache_bytecode()
    except KeyboardInterrupt:  # outside the main thread no handler is in place
        interrupt.caught = "SIGINT"
    if interrupt.caught:
        print(f"atlas_defrag: error: {args.input}: interrupted ({interrupt.caught}): nothing was written",
              file=sys.stderr)
        return EXIT_INTERRUPTED
    pkg = _package()
    problem = importlib.import_module(pkg.__name__ + ".native_check").problem(pkg.__name__)
    if problem:
        print(f"atlas_defrag: error: {problem}", file=sys.stderr)
        return 1
    token = importlib.import_module(pkg.__name__ + "._native").CancelToken()
    interrupt.attach(token)
    try:
        report = run_one(args, token)
    except Exception as exc:  # every failure: reason on stderr, exit 1 (130 when interrupted)
        cancelled = type(exc).__name__ == "DefragCancelled" or token.cancelled
        msg = str(exc) if isinstance(exc, PreviousFilesKept) else \
            f"interrupted ({interrupt.caught or 'SIGINT'}): nothing was written" if cancelled else \
            str(exc) if isinstance(exc, BatchError) or type(exc).__name__ == "DefragError" \
            else f"{type(exc).__name__}: {exc}"
        print(f"atlas_defrag: error: {args.input}: {msg}", file=sys.stderr)
        try:
            _write_report(args.report, {"input": os.path.abspath(args.input),
                                        "output": os.path.abspath(args.output),
                                        "status": "cancelled" if cancelled else "error", "error": msg})
        except OSError as report_exc:
            print(f"atlas_defrag: error: nor could the report {args.report} be written: {report_exc}",
                  file=sys.stderr)
        return EXIT_INTERRUPTED if cancelled else 1
    try:
        _write_report(args.report, report)
    except OSError as exc:
        print(f"atlas_defrag: error: {args.output} was written, but not the report {args.report}: {exc}",
              file=sys.stderr)
        return 1
    for w in report["warnings"] + [w for o in report["objects"] for w in o.get("warnings", [])]:
        print(f"atlas_defrag: warning: {w}", file=sys.stderr)
    for o in report["objects"]:
        fitted = (f", {o.get('packing_cuts')} cuts for packing to stay within the source's texels"
                  if o.get("cut_to_fit") else "")
        detail = pkg.job.detail_text(o)
        raised = f", {detail}" if detail else ""
        print(f"atlas_defrag: {o['object']}: charts {o.get('charts_before')} -> {o.get('charts_after')}, "
              f"seam {o.get('seam_before', 0):.4g} -> {o.get('seam_after', 0):.4g}{fitted}{raised}")
    print(f"atlas_defrag: wrote {args.output} in {report['seconds']['total']:.1f} s")
    return 0


# --------------------------------------------------------------------------- many models
def _expand(inputs):
    """The model files of inputs (files, and folders' models), each once."""
    files, seen = [], set()
    for item in inputs:
        found = [os.path.join(item, name) for name in sorted(os.listdir(item)) if name.lower().endswith(INPUT_EXTS)] \
            if os.path.isdir(item) else [item]
        for f in found:
            if _real(f) not in seen:
                seen.add(_real(f))
                files.append(f)
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
        args = _schema().parsed(p, argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    problem = _image_format_problem(args.image_format, "." + args.format)
    if problem:
        print(f"atlas_defrag: error: {problem}", file=sys.stderr)
        return 2
    files = _without_outputs(_expand(args.inputs), args.out_dir)
    if not files:
        print("atlas_defrag: error: no input models", file=sys.stderr)
        return 2
    blender = _blender_exe(args.blender)
    if shutil.which(blender) is None:
        print(f"atlas_defrag: error: Blender not found: {blender} (set --blender or $BLENDER)", file=sys.stderr)
        return 2
    try:
        os.makedirs(args.out_dir, exist_ok=True)
    except OSError as exc:
        print(f"atlas_defrag: error: cannot make the output folder {args.out_dir}: {exc}", file=sys.stderr)
        return 2
    command = [blender, "--background", "--factory-startup", "--python-exit-code", "1",
               "--python", os.path.abspath(__file__), "--"]
    runner = _Runner(command, _passthrough(args), _blender_env(blender))
    jobs = _output_names(files, args.out_dir, args.format)
    counts = {"ok": 0, "skipped": 0, "failed": 0, "interrupted": 0}
    # SIGINT or SIGTERM: the children are told to stop (SIGINT), and no model starts after.
    previous = {s: signal.signal(s, lambda *_: runner.interrupt()) for s in _Interrupt.SIGNALS} \
        if threading.current_thread() is threading.main_thread() else {}
    try:
        with ThreadPoolExecutor(max_workers=max(1, args.jobs)) as pool:
            for f, out, status, err, warnings in pool.map(lambda job: runner.run(*job), jobs):
                print(f"atlas_defrag: {status}: {f} -> {out}" + (f"\n  {err}" if err else ""),
                      file=sys.stderr if status in ("failed", "interrupted") else sys.stdout)
                for line in warnings:
                    print(f"  {line}", file=sys.stderr)
                counts[status] += 1
    finally:
        _restore_handlers(previous)
    print(f"atlas_defrag: {counts['ok']} done, {counts['skipped']} skipped (output exists), "
          f"{counts['failed']} failed" + (f", {counts['interrupted']} interrupted" if runner.stopping else ""))
    if runner.stopping:
        return EXIT_INTERRUPTED
    return 1 if counts["failed"] else 0


def _passthrough(args) -> list:
    """The single-model arguments that repeat the options given here."""
    schema = _schema()
    out = []
    for o in schema.SCHEMA:
        out += schema.argument_words(o, getattr(args, o.name))
    for opt in ("uv_map", "texture"):
        value = getattr(args, opt)
        if value is not None:
            out += ["--" + opt.replace("_", "-"), str(value)]
    if args.keep_source_uv:
        out.append("--keep-source-uv")
    if args.image_format != "auto":
        out += ["--image-format", args.image_format, "--image-quality", str(args.image_quality)]
    return out


def _without_outputs(files, out_dir: str) -> list:
    """files less the models a run into out_dir wrote there before, in either
    output format (an earlier run may have written the other): a file in
    out_dir whose report beside it (see _output_names) names it as the output
    of another input. A name alone proves nothing: rock_2.obj may be a scan
    of its own, and so may rock.obj beside the report of a rock.glb."""
    out = _real(out_dir)

    def earlier_output(f: str) -> bool:
        stem = os.path.splitext(os.path.basename(f))[0]
        if _real(os.path.dirname(os.path.abspath(f))) != out:
            return False
        source, written = _report_paths(os.path.join(out_dir, f"{stem}.report.json"))
        return bool(source and written) and _real(source) != _real(f) and _real(written) == _real(f)

    return [f for f in files if not earlier_output(f)]


def _report_paths(report: str) -> tuple:
    """(input, output) the batch report at `report` names ('' for either
    without a report, or with one that is not ours)."""
    try:
        with open(report, encoding="utf-8") as f:
            paths = json.load(f)
        paths = (paths.get("input"), paths.get("output"))
    except (OSError, ValueError, AttributeError):
        return "", ""
    return tuple(p if isinstance(p, str) else "" for p in paths)


def _report_input(report: str) -> str:
    """The input the batch report at `report` names ('' without a report, or with one that is not ours)."""
    return _report_paths(report)[0]


def _made_from_another(report: str, model: str) -> bool:
    """Whether the report names an input other than model that is still
    there: an input moved since (another folder, machine or mount) keeps the
    outputs it made, and a rerun skips them."""
    source = _report_input(report)
    return bool(source) and _real(source) != _real(model) and os.path.isfile(source)


def _output_names(files, out_dir: str, fmt: str) -> list:
    """(input, output, report) per file, every output name distinct and none
    an input: a stem already taken (by an earlier file's stem or its _2 form,
    by an input, or by an earlier run's output of another input, as its
    report says) gets the next free _2, _3, ... So an earlier output of this
    input keeps its name, and is skipped."""
    taken, inputs = set(), {_real(f) for f in files}
    jobs = []
    for f in files:
        base = os.path.splitext(os.path.basename(f))[0]
        stem, k = base, 1
        while stem.lower() in taken or _real(os.path.join(out_dir, f"{stem}.{fmt}")) in inputs or \
                _made_from_another(os.path.join(out_dir, f"{stem}.report.json"), f):
            k += 1
            stem = f"{base}_{k}"
        taken.add(stem.lower())
        jobs.append((f, os.path.join(out_dir, f"{stem}.{fmt}"), os.path.join(out_dir, f"{stem}.report.json")))
    return jobs


def _blender_env(blender: str) -> dict:
    """The environment for Blender: no Python variables of this interpreter
    but the bytecode cache's (_cache_bytecode), and Blender's own folder first
    on PATH. A Blender linked against the
    system Python takes its prefix from the first python3 on PATH: a virtualenv
    or pyenv python3 there would hide the system numpy."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONHOME", "PYTHONPATH", "VIRTUAL_ENV", "PYTHONSTARTUP", "PYTHONUSERBASE")}
    cache = env.get("PYTHONPYCACHEPREFIX") or bytecode_cache_dir()
    if cache and _writable_cache(cache):  # private: Python would make it readable by all
        env["PYTHONPYCACHEPREFIX"] = cache  # Blender's start-up reads the cache too
    exe = shutil.which(blender)
    if exe:
        env["PATH"] = os.pathsep.join([os.path.dirname(os.path.realpath(exe)), env.get("PATH", "")])
    return env


class _Runner:
    """One Blender process per model; interrupt() stops starting new ones and
    passes SIGINT on to those running (each cancels and cleans up)."""

    def __init__(self, command, passthrough, env):
        self.command, self.passthrough, self.env = command, passthrough, env
        self.stopping = False
        self.running = set()
        self.lock = threading.Lock()

    def interrupt(self):
        with self.lock:
            self.stopping = True
            for proc in self.running:
                proc.send_signal(signal.SIGINT)

    def run(self, f, out, rep):
        """(input, output, status, error line, the model's warning lines)."""
        if os.path.isfile(out):
            return f, out, "skipped", "", []
        with self.lock:
            if self.stopping:
                return f, out, "interrupted", "not started", []
            proc = subprocess.Popen(self.command + [f, out, "--report", rep] + self.passthrough,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=self.env)
            self.running.add(proc)
        try:
            _, stderr = proc.communicate()
        finally:
            with self.lock:
                self.running.discard(proc)
        if proc.returncode == 0:
            return f, out, "ok", "", [ln for ln in stderr.splitlines() if ln.startswith("atlas_defrag: warning:")]
        err = [ln for ln in stderr.splitlines() if "atlas_defrag: error" in ln]
        err = err[-1] if err else stderr.strip()[-500:]
        if "No module named 'numpy'" in stderr:
            err += " (Blender found a python3 without numpy on PATH: run Blender's own Python or set --blender)"
        status = "interrupted" if self.stopping or proc.returncode == EXIT_INTERRUPTED else "failed"
        return f, out, status, err, []


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
