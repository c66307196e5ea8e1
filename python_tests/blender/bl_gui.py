# SPDX-License-Identifier: MIT
"""The interactive path in a real Blender window (3.x under Xvfb):
props dialog -> modal operator with a worker thread -> one undo; Esc cancels.

xvfb-run blender --factory-startup --enable-event-simulate --python bl_gui.py -- \
    --addon-parent DIR --out result.json
"""

import argparse
import json
import os
import sys
import time
import traceback

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
ap = argparse.ArgumentParser()
ap.add_argument("--addon-parent", required=True)
ap.add_argument("--out", required=True)
ap.add_argument("--timeout", type=float, default=300)
ARGS = ap.parse_args(argv)
sys.path.insert(0, ARGS.addon_parent)

import bpy  # noqa: E402
import numpy as np  # noqa: E402

import atlas_defrag  # noqa: E402
import blhelp as H  # noqa: E402
import bl_scenarios as S  # noqa: E402

atlas_defrag.register()
RESULT = {"blender": bpy.app.version_string, "background": bpy.app.background, "steps": {}}


def ctx():
    win = bpy.context.window_manager.windows[0]
    area = next(a for a in win.screen.areas if a.type == "VIEW_3D")
    region = next(r for r in area.regions if r.type == "WINDOW")
    return win, bpy.context.temp_override(window=win, screen=win.screen, area=area, region=region)


def done(name, ok, info=None):
    RESULT["steps"][name] = {"ok": ok, "info": info}
    with open(ARGS.out, "w") as f:
        json.dump(RESULT, f, indent=1, default=str)


def new_uvs(name):
    """The UVs of the object's first new map, per loop."""
    layer = next(u for u in bpy.data.objects[name].data.uv_layers if u.name.endswith("_defrag"))
    uv = np.empty(2 * len(layer.data), np.float32)
    layer.data.foreach_get("uv", uv)
    return uv


def new_uv_present(name):
    return any(uv.name.endswith("_defrag") for uv in bpy.data.objects[name].data.uv_layers)


OUTCOME = atlas_defrag.operators.last_outcome


def wait_outcome(timeout):
    """Yields until the running operator reports an outcome."""
    t0 = time.time()
    ticks = []
    while OUTCOME["status"] is None:
        assert time.time() - t0 < timeout, "the modal run did not end"
        ticks.append(round(time.time() - t0, 3))
        yield 0.05
    RESULT.setdefault("ticks", []).append((ticks, round(time.time() - t0, 3)))
    return len(ticks)


def confirm_dialog(win, override, **props):
    """Opens the operator's dialog and confirms it with Return: the run starts."""
    with override:
        res = bpy.ops.uv.defragment_atlas("INVOKE_DEFAULT", **props)
    assert res == {"RUNNING_MODAL"}, res  # the dialog is open
    yield 0.5
    t0 = time.time()
    win.event_simulate(type="RET", value="PRESS")
    win.event_simulate(type="RET", value="RELEASE")
    return time.time() - t0


def driver():
    """A generator stepped by a timer: yields seconds to wait."""
    obj = H.import_model(H.model_path("tetra"))
    name = obj.name
    before = H.object_state(name)
    win, override = ctx()

    # 1. Modal run (what OK in the dialog starts), UI live meanwhile.
    try:
        H.undo_push("before")
        OUTCOME["status"] = None
        t0 = time.time()
        call = yield from confirm_dialog(win, override)
        # Control is back in the event loop while the worker computes.
        assert OUTCOME["status"] is None, OUTCOME
        ticks = yield from wait_outcome(ARGS.timeout)
        assert OUTCOME["status"] == "finished", OUTCOME
        # The first tick comes before Blender handles Return. A run on the main
        # thread would end before the next tick, which would then see the outcome.
        assert ticks >= 2, f"the confirmed dialog blocked the event loop ({ticks} ticks)"
        yield 0.3
        S.check_result(name, before, None)
        H.undo()
        yield 0.3
        after = H.object_state(name)
        assert after == before, S._diff(before, after)
        done("modal_run_and_undo", True, {"ticks": ticks, "call_seconds": call, "seconds": time.time() - t0})
    except Exception:
        done("modal_run_and_undo", False, traceback.format_exc())

    # 2. Esc while the worker runs: cancelled, nothing written.
    try:
        win, override = ctx()
        OUTCOME["status"] = None
        yield from confirm_dialog(win, override)
        win.event_simulate(type="ESC", value="PRESS")
        win.event_simulate(type="ESC", value="RELEASE")
        yield from wait_outcome(60)
        assert OUTCOME["status"] == "cancelled", OUTCOME
        yield 0.3
        after = H.object_state(name)
        assert not new_uv_present(name), "Esc did not cancel"
        assert after == before, S._diff(before, after)
        done("escape_cancels", True)
    except Exception:
        done("escape_cancels", False, traceback.format_exc())

    # 3. The props dialog: invoke, confirm with Return.
    try:
        win, override = ctx()
        OUTCOME["status"] = None
        with override:
            res = bpy.ops.uv.defragment_atlas("INVOKE_DEFAULT")
        assert res == {"RUNNING_MODAL"}, res  # the dialog is open
        yield 0.5
        assert OUTCOME["status"] is None, OUTCOME
        win.event_simulate(type="RET", value="PRESS")
        win.event_simulate(type="RET", value="RELEASE")
        yield from wait_outcome(ARGS.timeout)
        assert OUTCOME["status"] == "finished", OUTCOME
        yield 0.3
        S.check_result(name, before, None)
        done("dialog_run", True, {"invoke": sorted(res)})
    except Exception:
        done("dialog_run", False, traceback.format_exc())

    # 4. One Atlas for All Selected, modal: one worker run writes both objects.
    try:
        plane = H.textured_plane(name="Second")
        H.make_active(bpy.data.objects[name])
        plane.select_set(True)
        win, override = ctx()
        OUTCOME["status"] = None
        yield from confirm_dialog(win, override, one_atlas=True)
        yield from wait_outcome(ARGS.timeout)
        assert OUTCOME["status"] == "finished", OUTCOME
        reports = OUTCOME["report"]
        assert [r["object"] for r in reports] == [name, plane.name], reports
        assert reports[0]["images"] == reports[1]["images"], reports
        assert new_uv_present(plane.name)
        done("modal_one_atlas", True, {"images": reports[0]["images"]})
    except Exception:
        done("modal_one_atlas", False, traceback.format_exc())

    # 5. The redo panel with Run Again after a dialog run: the job runs again, synchronously, with the new
    # settings (a redo keeps the invoke flag: it started a worker, which wrote nothing, and the next undo crashed).
    try:
        op = bpy.context.window_manager.operators[-1]
        op.properties.run_again, op.properties.padding = True, 8
        active = bpy.context.view_layer.objects.active.name
        uv_before = new_uvs(active)
        OUTCOME["status"] = None
        win, override = ctx()
        with override:
            res = bpy.ops.ed.undo_redo()  # what the redo panel calls
        assert res == {"FINISHED"}, res
        assert OUTCOME["status"] == "finished", OUTCOME  # already: nothing left running
        assert OUTCOME["report"][0]["padding"] == 8, OUTCOME["report"][0].get("padding")
        assert new_uv_present(active), [u.name for u in bpy.data.objects[active].data.uv_layers]
        assert not np.array_equal(new_uvs(active), uv_before), "the redo left the layout of padding 4"
        yield 0.3
        with override:
            bpy.ops.ed.undo()
        yield 0.3
        done("redo_run_again", True, {"redo": sorted(res)})
    except Exception:
        done("redo_run_again", False, traceback.format_exc())

    # 6. The dialog fills its UV Map field with the active object's default map, here one its image reads
    # through a UV Map node; kept as it is, the other selected object lays out its own default map, not a
    # map of that name it happens to have.
    try:
        for obj in list(bpy.data.objects):
            bpy.data.objects.remove(obj)
        win, override = ctx()
        with override:
            first, second, scan, own = S.planes_reading_their_own_maps()
        OUTCOME["status"] = None
        yield from confirm_dialog(win, override)
        yield from wait_outcome(ARGS.timeout)
        assert OUTCOME["status"] == "finished", OUTCOME
        maps = [[m.name for m in o.data.uv_layers] for o in (first, second)]
        assert maps[0][0] == f"{scan}_defrag" and maps[1][0] == f"{own}_defrag", maps
        done("dialog_default_maps", True, {"maps": maps})
    except Exception:
        done("dialog_default_maps", False, traceback.format_exc())


GEN = None


def tick():
    global GEN
    try:
        if GEN is None:
            GEN = driver()
        return next(GEN)
    except StopIteration:
        pass
    except Exception:
        done("driver", False, traceback.format_exc())
    RESULT["finished"] = True
    done("end", True)
    bpy.ops.wm.quit_blender()
    return None


bpy.app.timers.register(tick, first_interval=1.0)
