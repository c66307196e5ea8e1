# SPDX-License-Identifier: MIT
"""Atlas Defrag: repairs fragmented texture atlases of photogrammetry scans.

Python entry for scripts::

    import atlas_defrag            # or the add-on's package name
    report = atlas_defrag.defragment(obj, target_charts=0, weighting="3d")

One code base for Blender 3.x (legacy add-on, ``bl_info``) and 4.2+ (extension,
``blender_manifest.toml``). Relative imports only: as an extension the package
lives under ``bl_ext.<repository>.atlas_defrag``.
"""

bl_info = {
    "name": "Atlas Defrag",
    "author": "Atlas Defrag developers",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "3D Viewport > Object (or UV in Edit Mode), UV Editor > Image / UV, Sidebar > Atlas Defrag, "
                "File > Import > Textured Scan PLY",
    "description": "Merge fragmented UV charts of scanned meshes and bake new textures",
    "category": "UV",
    "support": "COMMUNITY",
}

import importlib

if "job" in locals():  # script reload: reload the submodules already loaded
    for _name in ("options", "job", "png_files", "ply_io", "native_check", "compat", "read_bpy", "write_bpy",
                  "ply_import", "api", "operators", "ui"):
        if _name in globals():
            importlib.reload(globals()[_name])

from . import job, options  # noqa: E402,F401  (no bpy: tools use them without Blender)
from .job import DefragCancelled, DefragError  # noqa: E402,F401

__all__ = ["defragment", "DefragError", "DefragCancelled", "register", "unregister"]

# Loaded on first use, so that importing the package needs no bpy.
_BPY_MODULES = ("compat", "read_bpy", "write_bpy", "ply_import", "api", "operators", "ui")


def __getattr__(name):
    if name in _BPY_MODULES:
        return importlib.import_module("." + name, __name__)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def defragment(obj, **options) -> dict:
    """Defragments the texture atlas of mesh object ``obj`` and returns the report.

    Keyword options: those of options.SCHEMA (README, *Options*), and uv_map
    (default: the active UV map, or the map the image maps read if they read
    none through it), storage ('PACK' or 'SAVE'), image_dir (with
    'SAVE'), duplicate_materials (True: rewire copies of every material;
    False: rewire them in place, with a warning naming those that objects
    drawing other meshes use; default: as the operator, copies of all when
    any is so used), new_map_first (default True: the new UV map
    at index 0, where FBX readers look), progress (callable(stage, fraction),
    called from the native worker threads: it must not touch bpy),
    cancel (a _native.CancelToken), wait_in_main_thread (the native work on a
    thread of its own, so that signal handlers run meanwhile: see api.defragment).

    The report has charts_before/after, seam_before/after, seconds, the new
    UV map, images and materials, and warnings. Raises DefragError with the
    reason (then nothing was changed).
    """
    from . import api
    return api.defragment(obj, **options)


def register():
    from . import operators, ui
    operators.register()
    ui.register()


def unregister():
    from . import operators, ui
    ui.unregister()
    operators.unregister()
