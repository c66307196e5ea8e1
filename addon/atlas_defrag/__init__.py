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
    "location": "UV Editor and 3D Viewport > UV > Defragment Texture Atlas",
    "description": "Merge fragmented UV charts of scanned meshes and bake new textures",
    "category": "UV",
    "support": "COMMUNITY",
}

if "bpy" in locals():  # script reload
    import importlib

    for _name in ("job", "compat", "read_bpy", "write_bpy", "api", "operators"):
        if _name in locals():
            importlib.reload(locals()[_name])

import bpy  # noqa: E402,F401

from . import api, compat, job, operators, read_bpy, write_bpy  # noqa: E402,F401
from .job import DefragCancelled, DefragError  # noqa: E402,F401

__all__ = ["defragment", "DefragError", "DefragCancelled", "register", "unregister"]


def defragment(obj, **options) -> dict:
    """Defragments the texture atlas of mesh object ``obj`` and returns the report.

    Keyword options: uv_map (default: the active UV map), target_charts
    (0 = automatic), weighting ('uv' or '3d'), padding (texels), output_size
    (0 = automatic: keeps the texel budget), max_page_size, density_scale,
    storage ('PACK' or 'SAVE'), image_dir (with 'SAVE'), duplicate_materials,
    progress (callable(stage, fraction)), cancel (a _native.CancelToken).

    The report has charts_before/after, seam_before/after, seconds, the new
    UV map, images and materials, and warnings. Raises DefragError with the
    reason (then nothing was changed).
    """
    return api.defragment(obj, **options)


def register():
    operators.register()


def unregister():
    operators.unregister()
