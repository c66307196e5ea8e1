# SPDX-License-Identifier: MIT
"""The add-on without a native module for this platform: registers, and says
which platform and Python its module is built for (at enable time and in the
operator's poll message). Run by test_bl_ui_bpy.py in Blender 3.4 and bpy.

blender -b --factory-startup --python bl_hidden_native.py -- ADDON_PARENT OUT.json
python bl_hidden_native.py ADDON_PARENT OUT.json
"""

import json
import sys

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
parent, out = argv
sys.path.insert(0, parent)

import bpy  # noqa: E402

import atlas_defrag  # noqa: E402

atlas_defrag.register()
res = {"blender": bpy.app.version_string, "poll": bpy.ops.uv.defragment_atlas.poll(),
       "problem": atlas_defrag.operators.native_problem()}
try:
    bpy.ops.uv.defragment_atlas()
except RuntimeError as exc:
    res["error"] = str(exc)
atlas_defrag.unregister()  # bpy 4.5 hangs at exit while an operator is registered
with open(out, "w") as f:
    json.dump(res, f)
