# SPDX-License-Identifier: MIT
"""Installs the add-on zip the way a user would, then runs a scenario with it.

Blender 3.x:  blender -b --factory-startup --python bl_install.py -- --zip Z --out R.json
              (BLENDER_USER_SCRIPTS points to a scratch folder)
bpy 4.x:      python bl_install.py --zip Z --out R.json
              (BLENDER_USER_RESOURCES points to a scratch folder)
"""

import argparse
import importlib
import json
import os
import sys
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from blhelp import MissingModel  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    p = argparse.ArgumentParser()
    p.add_argument("--zip", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--scenario", default="operator_tetra")
    args = p.parse_args(argv)
    import bpy
    res = {"blender": bpy.app.version_string}
    try:
        if bpy.app.version >= (4, 2, 0):
            res["install"] = sorted(bpy.ops.extensions.package_install_files(
                filepath=args.zip, repo="user_default", enable_on_install=True))
            module = "bl_ext.user_default.atlas_defrag"
        else:
            res["install"] = sorted(bpy.ops.preferences.addon_install(filepath=args.zip, overwrite=True))
            res["enable"] = sorted(bpy.ops.preferences.addon_enable(module="atlas_defrag"))
            module = "atlas_defrag"
        res["enabled"] = [a.module for a in bpy.context.preferences.addons if "atlas_defrag" in a.module]
        pkg = importlib.import_module(module)
        res["package"] = pkg.__file__
        native = importlib.import_module(module + "._native")
        res["native"] = native.__file__
        res["operator"] = hasattr(bpy.types, "UV_OT_defragment_atlas")
        import bl_scenarios as scenarios
        res["value"] = scenarios.SCENARIOS[args.scenario](pkg)
        res["ok"] = True
    except MissingModel as exc:
        res["skipped"] = str(exc)
    except BaseException:
        res["ok"] = False
        res["error"] = traceback.format_exc()
    with open(args.out, "w") as f:
        json.dump(res, f, indent=1, default=str)


main()
