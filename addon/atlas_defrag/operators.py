# SPDX-License-Identifier: MIT
"""The operator, its dialog and its menu entries."""

import threading
import time

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from . import api, compat, job
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


# The outcome of the last run, for scripts and tests: status is 'finished',
# 'cancelled' or 'error'; message is what was reported.
last_outcome = {"status": None, "message": ""}


def _outcome(status, message):
    last_outcome["status"] = status
    last_outcome["message"] = message


def _native_token():
    from . import _native
    return _native.CancelToken()


def _option_property(option):
    """The property of one option; with an Automatic toggle, its manual value."""
    common = {"name": option.label, "description": option.help}
    if option.choices:
        return EnumProperty(items=[(c.value.upper(), c.label, c.help) for c in option.choices],
                            default=option.default.upper(), **common)
    if option.kind is bool:
        return BoolProperty(default=option.default, **common)
    if option.low is not None:
        common["min"] = option.low
    if option.high is not None:
        common["max"] = option.high
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
_OptionProperties = type("_OptionProperties", (), {"__annotations__": _option_properties()})


class UV_OT_defragment_atlas(_OptionProperties, bpy.types.Operator):
    """Merge the UV charts of the active mesh into fewer, larger ones and bake
    new textures for them (the old UV map and images are kept)"""

    bl_idname = "uv.defragment_atlas"
    bl_label = "Defragment Texture Atlas"
    bl_options = {"REGISTER", "UNDO"}

    uv_map: StringProperty(name="UV Map", description="UV map to defragment (empty: the active one)",
                           options={"SKIP_SAVE"})
    storage: EnumProperty(
        name="Images", default="PACK",
        items=(("PACK", "Pack in .blend", "Pack the new images into the .blend file"),
               ("SAVE", "Save Beside .blend", "Save the new images as files next to the .blend file")))
    duplicate_materials: BoolProperty(
        name="Duplicate Materials", default=False,
        description="Rewire copies of the materials and leave the originals untouched")
    use_modal: BoolProperty(default=False, options={"HIDDEN", "SKIP_SAVE"})

    @classmethod
    def poll(cls, context):
        # Permissive on purpose: execute() explains what is missing.
        return context.scene is not None

    def _option_value(self, option):
        if option.automatic and getattr(self, _automatic_name(option)):
            return 0
        value = getattr(self, option.name)
        return value.lower() if option.choices else value

    def _settings(self) -> api.Settings:
        return api.Settings.from_kwargs(
            uv_map=self.uv_map or None, storage=self.storage,
            duplicate_materials=self.duplicate_materials,
            **{o.name: self._option_value(o) for o in SCHEMA})

    def invoke(self, context, event):
        obj = context.active_object
        try:
            layer = api.read_bpy.check_object(obj, self.uv_map or None)
        except DefragError as exc:
            return self._fail("error", str(exc))
        if not self.uv_map:
            self.uv_map = layer.name
        self.use_modal = not bpy.app.background and context.window is not None
        return context.window_manager.invoke_props_dialog(self, width=360)

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        obj = context.active_object
        if obj is not None and obj.type == "MESH":
            layout.prop_search(self, "uv_map", obj.data, "uv_layers")
        for option in SCHEMA:
            self._draw_option(layout, option)
        layout.prop(self, "storage")
        layout.prop(self, "duplicate_materials")

    def _draw_option(self, layout, option):
        if not option.automatic:
            layout.prop(self, option.name, expand=bool(option.choices))
            return
        col = layout.column(heading=option.label)
        col.prop(self, _automatic_name(option), text="Automatic")
        sub = col.column()
        sub.enabled = not getattr(self, _automatic_name(option))
        sub.prop(self, option.name)

    # -- synchronous path (background, scripts, redo) ------------------------
    def execute(self, context):
        obj = context.active_object
        try:
            settings = self._settings()
            read = api.prepare(obj, settings)
        except (DefragError, TypeError) as exc:
            return self._fail("error", str(exc))
        if self.use_modal and context.window is not None and not bpy.app.background:
            self.use_modal = False  # a redo of this operator runs synchronously
            return self._start_modal(context, obj, read, settings)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            result = api.compute(read, settings,
                                 progress=lambda s, f: wm.progress_update(int(100 * f)))
            report = api.finish(obj, read, result, settings)
        except DefragCancelled:
            return self._fail("cancelled", "Cancelled: nothing was changed")
        except DefragError as exc:
            return self._fail("error", str(exc))
        finally:
            wm.progress_end()
        self._report_done(report)
        return {"FINISHED"}

    def _fail(self, status, message):
        _outcome(status, message)
        self.report({"WARNING"} if status == "cancelled" else {"ERROR"}, message)
        return {"CANCELLED"}

    def _report_done(self, report):
        for w in report.get("warnings", []):
            self.report({"WARNING"}, w)
        msg = (f"Defragmented '{report['object']}': {job.summary(report)}; "
               f"new UV map '{report['uv_map']}'")
        _outcome("finished", msg)
        self.report({"INFO"}, msg)

    # -- modal path: worker thread + timer ------------------------------------
    def _start_modal(self, context, obj, read, settings):
        try:
            token = _native_token()
        except ImportError as exc:
            return self._fail("error", f"The native module is missing: {exc}")
        run = _Run(read, settings, token)
        self._run = run
        self._object_name = obj.name
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.progress_begin(0, 100)
        compat.status_text_set(context, "Defragmenting texture atlas... (Esc to cancel)")
        wm.modal_handler_add(self)
        run.thread = threading.Thread(target=run.work, name="atlas_defrag", daemon=True)
        run.thread.start()
        return {"RUNNING_MODAL"}

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
            context.window_manager.progress_update(int(100 * run.fraction))
            if not run.cancel_requested:
                compat.status_text_set(
                    context, f"Defragmenting texture atlas: {run.stage} {100 * run.fraction:.0f}% "
                             f"({time.perf_counter() - run.started:.0f} s, Esc to cancel)")
            return {"RUNNING_MODAL"}
        self._end_modal(context)
        if run.cancel_requested or isinstance(run.error, DefragCancelled):
            return self._fail("cancelled", "Cancelled: nothing was changed")
        if run.error is not None:
            msg = str(run.error) if isinstance(run.error, DefragError) else \
                f"{type(run.error).__name__}: {run.error}"
            return self._fail("error", msg)
        obj = bpy.data.objects.get(self._object_name)
        if obj is None:
            return self._fail("error", "The object was removed during the run: nothing was written")
        try:
            report = api.finish(obj, run.read, run.result, run.settings)
        except DefragError as exc:
            return self._fail("error", str(exc))
        self._report_done(report)
        return {"FINISHED"}

    def cancel(self, context):
        # Blender ends the modal (window closed, file loaded): stop the worker.
        run = getattr(self, "_run", None)
        if run is not None:
            run.token.cancel()
            run.thread.join(timeout=30)
        self._end_modal(context)


def menu_func(self, context):
    self.layout.separator()
    self.layout.operator(UV_OT_defragment_atlas.bl_idname, icon="UV")


MENUS = ("IMAGE_MT_uvs", "VIEW3D_MT_uv_map")
classes = (UV_OT_defragment_atlas,)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    for name in MENUS:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.append(menu_func)


def unregister():
    for name in MENUS:
        menu = getattr(bpy.types, name, None)
        if menu is not None:
            menu.remove(menu_func)
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
