# SPDX-License-Identifier: MIT
"""Runs scenarios.py inside a Blender executable and writes their outcome as JSON.

blender --background --factory-startup --python-exit-code 1 --python bl_runner.py -- \
    --addon-parent DIR --out result.json SCENARIO [SCENARIO...]
(--addon-parent '' : use the add-on enabled through Blender's preferences, module atlas_defrag)
"""

import argparse
import json
import os
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    p = argparse.ArgumentParser()
    p.add_argument("--addon-parent", default="")
    p.add_argument("--out", required=True)
    p.add_argument("scenarios", nargs="+")
    args = p.parse_args(argv)
    if args.addon_parent:
        sys.path.insert(0, args.addon_parent)
    import bpy
    import atlas_defrag
    if not hasattr(bpy.types, "UV_OT_defragment_atlas"):
        atlas_defrag.register()
    import bl_scenarios as scenarios
    from blhelp import MissingModel
    results = {"blender": bpy.app.version_string, "package": atlas_defrag.__file__, "results": {}}
    for name in args.scenarios:
        t = time.perf_counter()
        try:
            value = scenarios.SCENARIOS[name](atlas_defrag)
            results["results"][name] = {"ok": True, "value": value}
        except MissingModel as exc:
            results["results"][name] = {"ok": False, "skipped": str(exc)}
        except BaseException:
            results["results"][name] = {"ok": False, "error": traceback.format_exc()}
        results["results"][name]["seconds"] = time.perf_counter() - t
        with open(args.out, "w") as f:
            json.dump(results, f, indent=1, default=str)


main()
