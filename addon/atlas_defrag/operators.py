# SPDX-License-Identifier: MIT
"""The operators (defragment, import a textured PLY scan), the dialog and the menu entries."""

import os
import re
import threading
import time
from dataclasses import replace

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty
from bpy_extras.io_utils import ImportHelper

from . import api, compat, job, native_check, ply_import, read_bpy, write_bpy
from .job import DefragCancelled, DefragError
from .options import SCHEMA

# Events that may pass through while the worker runs (view navigation only).
_NAVIGATION = {
    "MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "WHEELINMOUSE", "WHEELOUTMOUSE",
    "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE", "MOUSEMOVE", "INBETWEEN_MOUSEMOVE",
    "NDOF_MOTION", "WINDOW_DEACTIVATE", "TIMER_REPORT",
}


class _Run:
    """State shared with the worker thread: plain Python, no bpy."""

    def __init__(self, read, settings, cancel_token):
        self.read = read
        self.settings = settings
        self.token = cancel_token
        self.stage = "starting"
        self.fraction = 0.0
        self.result = None
        self.error = None
        self.cancel_requested = False
        self.started = time.perf_counter()
        self.thread = None

    def progress(self, stage, fraction):
        self.stage = stage
        self.fraction = fraction

    def work(self):
        try:
            self.result = api.compute(self.read, self.settings, progress=self.progress, cancel=self.token)
        except BaseException as exc:  # reported on the main thread
            self.error = exc

    def start(self):
        """work() on a thread of its own, while this (the main) thread reads
        the images' pixels, which the worker needs only once the layout is done."""
        self.thread = threading.Thread(target=self.work, name="atlas_defrag", daemon=True)
        self.thread.start()
        read_bpy.fetch_pixels(self.read.job)

    def wait(self, each_step):
        """The result of the native work, run on a thread of its own while
        this thread reads the pixels, then calls each_step() every 0.05 s: the
        native progress comes from worker threads, where bpy must not be touched."""
        return api.on_worker_thread(api.compute, self.read, self.settings, progress=self.progress,
                                    cancel=self.token, each_step=each_step,
                                    meanwhile=lambda: read_bpy.fetch_pixels(self.read.job))


# The outcome of the last run, for scripts and tests: status is 'finished',
# 'cancelled' or 'error'; message is what was reported; report the run's
# report (a list, one per object) or None.
last_outcome = {"status": None, "message": "", "report": None}


def _outcome(status, message, report=None):
    last_outcome["status"] = status
    last_outcome["message"] = message
    last_outcome["report"] = report


# Why adjacent charts stayed apart (report['aggregate_stops']), in words.
STOP_REASONS = {
    "not_disk": "the merged chart would have a hole or a handle",
    "non_manifold": "they meet at a non-manifold or flipped edge",
    "normal_coherence": "the merged chart would curve too far to flatten without stretching",
    "max_chart_faces": "the merged chart would exceed the largest chart size",
    "min_chart_fraction": "the smaller chart is too large a share of the surface",
    "feasible": "nothing refused them: the Target Charts count was reached first",
}


def stop_text(report) -> str:
    """Why the aggregation stopped, e.g. '120 pairs: the merged chart would have
    a hole or a handle'; empty when no pair was left."""
    stops = report.get("aggregate_stops") or {}
    parts = [f"{n} pair{'s' if n != 1 else ''}: {STOP_REASONS.get(k, k)}"
             for k, n in sorted(stops.items(), key=lambda kv: -kv[1]) if n]
    return ("Adjacent charts left apart because " + "; ".join(parts)) if parts else ""


def image_text(report) -> str:
    """The new images with their sizes, and their texel density against the
    source's when it differs (asked for, raised by the colour guard or shrunk
    to fit)."""
    names = []
    for name in report.get("images", []):
        img = bpy.data.images.get(name)
        names.append(f"{name} ({img.size[0]}x{img.size[1]})" if img is not None else name)
    text = "New images: " + (", ".join(names) or "none")
    scale = report.get("scale")
    if scale is not None and abs(scale - 1.0) > 1e-3:
        text += f"; texel density {scale:.3g}x the source's" + (" (shrunk to fit)" if report.get("shrunk") else "")
    return text


def report_lines(report) -> list:
    """What the Info log and the panel show after a run."""
    others = [n for n in report.get("atlas_objects", []) if n != report["object"]]
    shared = f" (one atlas with {', '.join(repr(n) for n in others)})" if others else ""
    lines = [f"Defragmented '{report['object']}'{shared}: {job.summary(report)}; new UV map '{report['uv_map']}'",
             image_text(report)]
    stops = stop_text(report)
    return lines + ([stops] if stops else [])


def native_problem() -> str:
    """Why the native module does not load here ('' when it does)."""
    return native_check.problem(__package__)


def _native_token():
    from . import _native
    return _native.CancelToken()


def _option_property(option):
    """The property of one option; with an Automatic toggle, its manual value."""
    common = {"name": option.label, "description": option.help}
    if option.choices:  # upper case, as Blender spells enum items (and saved presets hold them)
        return EnumProperty(items=[(c.value.upper(), c.label, c.help) for c in option.choices],
                            default=option.default.upper(), **common)
    if option.kind is bool:
        return BoolProperty(default=option.default, **common)
    # Soft bounds only: the sliders stop there, while a value a script or the
    # keyboard gives beyond them (0 for automatic, or out of range) reaches
    # the options' check, which takes it or refuses it in words, instead of
    # Blender clamping it without a word.
    if option.low is not None:
        common["soft_min"] = option.low
    if option.high is not None:
        common["soft_max"] = option.high
    if option.unit == "texels":
        common["subtype"] = "PIXEL"
    make = IntProperty if option.kind is int else FloatProperty
    return make(default=option.manual_default if option.automatic else option.default, **common)


def _automatic_name(option) -> str:
    return "automatic_" + option.name


def _option_properties() -> dict:
    props = {}
    for o in SCHEMA:
        if o.automatic:
            props[_automatic_name(o)] = BoolProperty(name="Automatic", default=True,
                                                     description=f"Automatic: {o.automatic}")
        props[o.name] = _option_property(o)
    return props


# The options' properties as a mixin: bpy collects the annotations of base classes too.
# The panel's settings (ui.py) are the same mixin on a PropertyGroup.
_OptionProperties = type("_OptionProperties", (), {"__annotations__": _option_properties()})


class WriteProperties:
    """How the result is written into Blender (not options of the native job)."""

    storage: EnumProperty(
        name="Images", default="PACK",
        items=(("PACK", "Pack in .blend", "Pack the new images into the .blend file"),
               ("SAVE", "Save Beside .blend", "Save the new images as files next to the .blend file")))
    duplicate_materials: BoolProperty(
        name="Duplicate Materials", default=False,
        description="Rewire copies of the materials and leave the originals untouched")
    new_map_first: BoolProperty(
        name="New Map First", default=True,
        description="Put the new UV map first (the one at index 0 moves to the end): FBX readers "
                    "and game engines texture through the first UV map")
    one_atlas: BoolProperty(
        name="One Atlas for All Selected", default=False,
        description="Pack the charts of every selected mesh into one shared atlas (shared new images) "
                    "instead of one atlas per mesh")


def draw_settings(layout, data) -> None:
    """The options and write properties of data (the operator or the panel's settings)."""
    for option in SCHEMA:
        if not option.automatic:
            layout.prop(data, option.name, expand=bool(option.choices))
            continue
        col = layout.column(heading=option.label)
        col.prop(data, _automatic_name(option), text="Automatic")
        sub = col.column()
        sub.enabled = not getattr(data, _automatic_name(option))
        sub.prop(data, option.name)
    for name in WriteProperties.__annotations__:
        layout.prop(data, name)


def setting_names() -> list:
    """Every property the panel's settings and the operator share."""
    names = []
    for o in SCHEMA:
        names += [_automatic_name(o)] if o.automatic else []
        names.append(o.name)
    return names + list(WriteProperties.__annotations__)


class UV_OT_defragment_atlas(_OptionProperties, WriteProperties, bpy.types.Operator):
    bl_idname = "uv.defragment_atlas"
    bl_label = "Defragment Texture Atlas"
    bl_description = ("Merge the UV charts of the selected meshes into fewer, larger ones and bake "
                      "new textures for them (the old UV map and images are kept)")
    bl_options = {"REGISTER", "UNDO", "PRESET"}

    uv_map: StringProperty(name="UV Map", options={"SKIP_SAVE"},
                           description="UV map to defragment (empty: the active one, or the one the image maps "
                                       "read if they read none through it)")
    run_again: BoolProperty(
        name="Run Again", default=False, options={"SKIP_SAVE"},
        description="Re-run the whole job with the changed settings (Blender waits until it ends)")

    @classmethod
    def poll(cls, context):
        problem = native_problem()
        if problem:
            cls.poll_message_set(problem)
            return False
        # Otherwise permissive: invoke() explains what is missing.
        return context.scene is not None

    def _option_value(self, option):
        if option.automatic and getattr(self, _automatic_name(option)) and not self._given_alone(option):
            return 0
        value = getattr(self, option.name)
        if option.kind is float:  # Blender keeps it in single precision: 0.8 reads 0.800000011920929
            return float(f"{value:.7g}")
        return value.lower() if option.choices else value

    def _given_alone(self, option) -> bool:
        """True when a script gave the option's value but not its Automatic
        toggle: the value is what it asked for (the dialog sets every toggle)."""
        given = self.properties.is_property_set
        return given(option.name) and not given(_automatic_name(option))

    def _settings(self, obj=None) -> api.Settings:
        # The UV map chosen in the dialog is the active object's; the others use a map of
        # that name if they have one, else their default map (read_bpy.check_object), as
        # they do when the field keeps the default invoke filled in.
        chosen = self.uv_map != getattr(self, "_filled_uv_map", "")
        uv_map = self.uv_map if obj is None or chosen and self.uv_map in obj.data.uv_layers else None
        return api.Settings.from_kwargs(
            uv_map=uv_map or None, storage=self.storage,
            duplicate_materials=self.duplicate_materials, new_map_first=self.new_map_first,
            **{o.name: self._option_value(o) for o in SCHEMA})

    def invoke(self, context, event):
        try:
            objects = targets(context)
            for obj in objects:
                api.read_bpy.check_textures(obj, self.uv_map if obj == objects[0] else None)
        except DefragError as exc:
            return self._fail("error", str(exc))
        except Exception as exc:  # a message, not a traceback in the UI
            return self._fail("error", _internal_error(exc))
        if not self.uv_map:
            # Kept as it is, this default of the active object's leaves the others theirs.
            self.uv_map = self._filled_uv_map = api.read_bpy.check_object(objects[0]).name
        for option in SCHEMA:  # the dialog's toggles decide, whatever values a last run left
            if option.automatic:
                setattr(self, _automatic_name(option), getattr(self, _automatic_name(option)))
        return context.window_manager.invoke_props_dialog(self, width=360)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        if self._has_run(context):  # the redo panel, not the dialog
            box = layout.box()
            box.label(text="A change here re-runs the whole job, and Blender waits for it", icon="INFO")
            box.prop(self, "run_again")
        obj = context.active_object
        if obj is not None and obj.type == "MESH":
            layout.prop_search(self, "uv_map", obj.data, "uv_layers")
        draw_settings(layout, self)

    def _has_run(self, context) -> bool:
        """True once this operator finished (it is then among the registered ones)."""
        me = self.as_pointer()
        return any(op.as_pointer() == me for op in context.window_manager.operators)

    # -- synchronous path (background, scripts, confirmed redo) ---------------
    def execute(self, context):
        if self.options.is_repeat and not self.run_again:
            # Blender restores the previous result when a redo is cancelled. Blender 3.4 flags a redo
            # as a Repeat Last too, so Shift+R cannot be told apart: it does not re-run the job either.
            self.report({"INFO"}, "Tick 'Run Again' in the Adjust Last Operation panel (F9) to re-run the job "
                                  "with these settings; Repeat Last does not re-run it")
            return {"CANCELLED"}
        try:
            objects = targets(context)
            self._left_out = left_out(context, objects)
            jobs = self._jobs(objects)
        except (DefragError, TypeError, ValueError) as exc:
            return self._fail("error", str(exc))
        if self.options.is_invoke and not self.options.is_repeat and context.window is not None \
                and not bpy.app.background:
            # The run the dialog confirms goes to a worker thread. A redo or a repeat keeps the
            # invoke flag of the run it repeats, but must end before it returns: Blender undoes
            # and frees around it, and a worker left running wrote nothing and crashed the next undo.
            return self._start_modal(context, jobs)
        units = self._units(jobs)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        reports, k = [], 0
        try:
            for k, unit in enumerate(units):
                run = _Run(_prepare(unit), unit[0][1], None)
                result = run.wait(lambda k=k, run=run: wm.progress_update(int(100 * (k + run.fraction) / len(units))))
                for report in _finish(unit, run.read, result):
                    reports.append(report)
        except DefragCancelled:
            return self._end(context, reports, "Cancelled: nothing was changed" if not reports else "Cancelled")
        except DefragError as exc:
            return self._end(context, reports, str(exc) + _not_tried(units[k:], 1))
        except Exception as exc:  # the write rolled its object back; the objects done stay
            return self._end(context, reports, _internal_error(exc) + _not_tried(units[k:], 1))
        finally:
            wm.progress_end()
        return self._end(context, reports, None)

    def _jobs(self, objects) -> list:
        """(object, settings) per object; objects done one at a time that
        share a material, or share it with objects not selected, rewire
        copies of it (api.shared_materials)."""
        shared = api.shared_materials(objects, among_them=not (self.one_atlas and len(objects) > 1))
        jobs = []
        for obj in objects:  # the first must have the UV map named; the others use it where they have it
            settings = self._settings(None if obj is objects[0] else obj)
            if api.uses_any(obj, shared):
                settings = replace(settings, duplicate_materials=True)
            jobs.append((obj, settings))
        return jobs

    def _units(self, jobs) -> list:
        """The runs, each a list of (object, settings): one per object, or
        one over all of them (One Atlas for All Selected)."""
        return [jobs] if self.one_atlas and len(jobs) > 1 else [[j] for j in jobs]

    def _end(self, context, reports, error):
        """Reports the objects done and the error that stopped the rest. With
        some objects done the run FINISHED, so that one undo step takes them back."""
        if reports:
            self._report_done(context, reports)
        if error is None:
            return {"FINISHED"}
        status = "cancelled" if error.startswith("Cancelled") else "error"
        self._fail(status, _done_before(reports) + error)
        return {"FINISHED"} if reports else {"CANCELLED"}

    def _fail(self, status, message):
        message = dialog_words(message)
        _outcome(status, message)
        self.report({"WARNING"} if status == "cancelled" else {"ERROR"}, message)
        return {"CANCELLED"}

    def _report_done(self, context, reports):
        reports[0].setdefault("warnings", []).extend(getattr(self, "_left_out", ()))
        lines = []
        for report in reports:
            for w in report.get("warnings", []):
                self.report({"WARNING"}, w)
            lines += report_lines(report)
        for line in lines:
            self.report({"INFO"}, line)
        _outcome("finished", "\n".join(lines), reports)
        show_in_image_editors(context, reports)

    # -- modal path: one worker thread per run in turn + timer ----------------
    def _start_modal(self, context, jobs):
        try:
            _native_token()
        except ImportError as exc:
            return self._fail("error", f"The native module is missing: {exc}")
        self._queue = [[(obj.name, settings) for obj, settings in unit] for unit in self._units(jobs)]
        self._count = len(self._queue)
        self._reports = []
        self._run = None
        error = self._next_run()
        if error:
            return self._fail("error", error)
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        compat.status_text_set(context, "Defragmenting texture atlas... (Esc to cancel)")
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def _next_run(self) -> str:
        """Reads the next queued run's objects and starts its worker; an error message or ''."""
        named = self._queue.pop(0)
        unit, error = _resolve(named, "during the run")
        if error:
            return error
        try:
            read = _prepare(unit)
        except DefragError as exc:
            return str(exc)
        self._unit = named
        self._run = _Run(read, unit[0][1], _native_token())
        self._run.start()
        return ""

    def _end_modal(self, context):
        wm = context.window_manager
        if getattr(self, "_timer", None) is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        wm.progress_end()
        compat.status_text_set(context, None)

    def modal(self, context, event):
        run = self._run
        if event.type == "ESC" and event.value == "PRESS" and not run.cancel_requested:
            run.cancel_requested = True
            run.token.cancel()
            compat.status_text_set(context, "Cancelling...")
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            return {"PASS_THROUGH"} if event.type in _NAVIGATION else {"RUNNING_MODAL"}
        if run.thread.is_alive():
            done = (self._count - len(self._queue) - 1 + run.fraction) / self._count
            context.window_manager.progress_update(int(100 * done))
            if not run.cancel_requested:
                which = f" ({', '.join(n for n, _ in self._unit)})" if self._count > 1 else ""
                compat.status_text_set(
                    context, f"Defragmenting texture atlas{which}: {run.stage} {100 * run.fraction:.0f}% "
                             f"({time.perf_counter() - run.started:.0f} s, Esc to cancel)")
            return {"RUNNING_MODAL"}
        try:
            error = self._finish_run(run)
            if error is None and self._queue:
                error = self._next_run() or None
                if error is None:
                    return {"RUNNING_MODAL"}
        except Exception as exc:  # reported, so that the timer and status text go with the modal
            error = f"{type(exc).__name__}: {exc}"
        if error is not None and not error.startswith("Cancelled"):
            error += _not_tried(self._queue, 0)
        self._end_modal(context)
        return self._end(context, self._reports, error)

    def _finish_run(self, run):
        """Writes a finished worker's result; the error message, or None."""
        if run.cancel_requested or isinstance(run.error, DefragCancelled):
            return "Cancelled: nothing was changed" if not self._reports else "Cancelled"
        if run.error is not None:
            return str(run.error) if isinstance(run.error, DefragError) else \
                f"{type(run.error).__name__}: {run.error}"
        unit, error = _resolve(self._unit, "during the run: nothing was written")
        if error:
            return error
        try:
            for report in _finish(unit, run.read, run.result):
                self._reports.append(report)
        except DefragError as exc:
            return str(exc)
        return None

    def cancel(self, context):
        # Blender ends the modal (window closed, file loaded): stop the worker.
        run = getattr(self, "_run", None)
        if run is not None:
            run.token.cancel()
            run.thread.join(timeout=30)
        self._end_modal(context)


def targets(context) -> list:
    """The meshes to defragment: the active object first, then the other
    selected meshes, each mesh once (linked duplicates share it)."""
    active = context.active_object
    api.read_bpy.check_object(active)
    if active.mode == "OBJECT" and active not in getattr(context, "selected_objects", [active]):  # overrides too
        hidden = not active.visible_get()
        raise DefragError(f"The active object '{active.name}' is " + ("hidden (in the viewport), so not selected: "
                          "unhide it and select it" if hidden else "not selected: select it") +
                          ", or make one of the selected meshes active")
    out, seen = [active], {active.data.name}
    for obj in getattr(context, "selected_objects", []):
        if obj.type == "MESH" and obj.data.name not in seen:
            seen.add(obj.data.name)
            out.append(obj)
    return out


def left_out(context, objects) -> list:
    """A warning for each selected object that was not defragmented because
    it draws a mesh taken already (a linked duplicate) with materials of its
    own (slots linked to the object): those still read the old UV map."""
    taken = {obj.data.name: obj for obj in objects}
    out = []
    for obj in getattr(context, "selected_objects", []):
        first = taken.get(obj.data.name) if obj.type == "MESH" else None
        if first is None or obj == first:
            continue
        theirs = {slot.material for slot in first.material_slots}
        own = sorted({slot.material.name for slot in obj.material_slots
                      if slot.link == "OBJECT" and slot.material and slot.material not in theirs})
        if own:
            out.append(f"'{obj.name}' shares its mesh with '{first.name}' but draws it with material(s) of its "
                       f"own, left as they were (old UV map and images): {', '.join(own)}")
    return out


def _resolve(named, when: str):
    """[(object, settings)] of [(name, settings)], and '' or the error
    naming an object removed meanwhile."""
    unit = [(bpy.data.objects.get(name), settings) for name, settings in named]
    gone = [name for (name, _), (obj, _) in zip(named, unit) if obj is None]
    return unit, (f"The object '{gone[0]}' was removed {when}" if gone else "")


def _prepare(unit):
    """The read of one run: one object's, or the shared read of several; the
    pixels come later (_Run reads them while its worker runs the layout)."""
    with api.as_defrag_error():
        if len(unit) == 1:
            return api.prepare(*unit[0], pixels_later=True)
        return api.prepare_shared([obj for obj, _ in unit], [s for _, s in unit], pixels_later=True)


def _finish(unit, read, result):
    """Writes one run's result, yielding the report of each object."""
    with api.as_defrag_error():
        if len(unit) == 1:
            yield api.finish(unit[0][0], read, result, unit[0][1])
            return
        yield from api.finish_shared([obj for obj, _ in unit], read, result, [s for _, s in unit])


def _internal_error(exc: Exception) -> str:
    """The message for an error the add-on did not foresee."""
    return f"Internal error ({type(exc).__name__}: {exc}): nothing more was changed; please report it"


def _not_tried(units, skip: int) -> str:
    """What an error message adds about the runs it stopped: units past the
    first `skip` ones (the one that failed), as [(object or name, settings)]."""
    names = [o if isinstance(o, str) else o.name for unit in units[skip:] for o, _ in unit]
    return f" (not tried: {', '.join(names)})" if names else ""


def _done_before(reports) -> str:
    if not reports:
        return ""
    return "Done for " + ", ".join(f"'{r['object']}'" for r in reports) + " (undo to revert); then: "


def dialog_words(message: str) -> str:
    """A message with the options' internal names replaced by the dialog's labels."""
    for o in SCHEMA:
        message = re.sub(rf"\b{o.name}\b", f"'{o.label}'", message)
    return message


def show_in_image_editors(context, reports) -> None:
    """Image Editors showing a source image show its new counterpart."""
    new_by_source = {}
    for report in reports:
        for name in report.get("images", []):
            new_by_source.setdefault(name.split(write_bpy.SUFFIX)[0], bpy.data.images.get(name))
    screen = getattr(context, "screen", None)
    for area in (screen.areas if screen is not None else []):
        if area.type != "IMAGE_EDITOR":
            continue
        space = area.spaces.active
        shown = space.image
        if shown is not None:
            new = new_by_source.get(write_bpy.image_stem(shown.name))
        else:
            new = next(iter(new_by_source.values()), None)
        if new is not None:
            space.image = new
            area.tag_redraw()


def menu_func(self, context):
    self.layout.separator()
    self.layout.operator(UV_OT_defragment_atlas.bl_idname, icon="UV")


class IMPORT_MESH_OT_textured_scan_ply(bpy.types.Operator, ImportHelper):
    """Import a textured PLY scan with its UVs per face (OpenMVS, MeshLab) or per vertex, and a material per TextureFile image"""
    bl_idname = "import_mesh.textured_scan_ply"
    bl_label = "Textured Scan (.ply)"
    bl_options = {"REGISTER", "UNDO"}
    filename_ext = ".ply"
    filter_glob: StringProperty(default="*.ply", options={"HIDDEN"})

    def execute(self, context):
        try:
            obj, missing, notes = ply_import.import_ply(self.filepath)
        except (OSError, ValueError, MemoryError) as exc:
            self.report({"ERROR"}, f"Cannot import {os.path.basename(self.filepath)}: {str(exc) or 'out of memory'}")
            return {"CANCELLED"}
        if missing:
            self.report({"WARNING"}, f"Texture files not found beside the PLY: {', '.join(missing)}")
        for note in notes:
            self.report({"WARNING"}, note)
        for other in context.view_layer.objects:
            other.select_set(False)
        obj.select_set(True)
        context.view_layer.objects.active = obj
        return {"FINISHED"}


def import_menu_func(self, context):
    self.layout.operator(IMPORT_MESH_OT_textured_scan_ply.bl_idname, text="Textured Scan PLY (Atlas Defrag)")


# Edit Mode: the UV menus. Object Mode, where a user lands after importing a
# scan: the Object menu and the UV Editor's Image menu (menu search finds these).
MENUS = ("IMAGE_MT_uvs", "VIEW3D_MT_uv_map", "VIEW3D_MT_object", "IMAGE_MT_image")
classes = (UV_OT_defragment_atlas, IMPORT_MESH_OT_textured_scan_ply)


def _menu_entries():
    """(menu, draw function) pairs this add-on adds, of the menus this Blender has."""
    pairs = [(name, menu_func) for name in MENUS] + [("TOPBAR_MT_file_import", import_menu_func)]
    return [(getattr(bpy.types, name), func) for name, func in pairs if getattr(bpy.types, name, None)]


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for menu, func in _menu_entries():
        menu.append(func)


def unregister():
    for menu, func in _menu_entries():
        menu.remove(func)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
