# SPDX-License-Identifier: MIT
"""The sidebar panel (3D Viewport and UV Editor), the operator presets, the
add-on preferences and the message shown when the native module cannot load."""

import os

import bpy
from bpy.props import PointerProperty

from . import operators
from .operators import UV_OT_defragment_atlas, _OptionProperties, WriteProperties

CATEGORY = "Atlas Defrag"

# Operator presets shipped with the add-on: file name -> settings.
PRESETS = {
    "Game: power-of-two": {"automatic_fixed_page_size": False, "fixed_page_size": 2048, "padding": 8,
                           "new_map_first": True},
    "Archive: keep density": {"automatic_fixed_page_size": True, "density_scale": 1.0,
                              "max_page_size": 16384, "padding": 4, "duplicate_materials": True},
}
PRESET_DIR = os.path.join("presets", "operator", UV_OT_defragment_atlas.bl_idname)


class AtlasDefragSettings(_OptionProperties, WriteProperties, bpy.types.PropertyGroup):
    """The panel's settings, saved with the scene: the operator's own properties."""


class _Panel:
    bl_label = "Defragment Texture Atlas"
    bl_region_type = "UI"
    bl_category = CATEGORY

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        problem = operators.native_problem()
        if problem:
            _wrapped(layout.box(), problem, icon="ERROR")
        settings = context.scene.atlas_defrag
        operators.draw_settings(layout, settings)
        op = layout.operator(UV_OT_defragment_atlas.bl_idname, icon="UV")
        for name in operators.setting_names():
            setattr(op, name, getattr(settings, name))
        _draw_last_report(layout.box())


def _draw_last_report(layout) -> None:
    outcome = operators.last_outcome
    if outcome["status"] is None:
        layout.label(text="No run yet in this session")
        return
    icon = {"finished": "CHECKMARK", "cancelled": "CANCEL"}.get(outcome["status"], "ERROR")
    for k, line in enumerate(outcome["message"].splitlines()):
        _wrapped(layout, line, icon=icon if k == 0 else "BLANK1")


def _wrapped(layout, text: str, icon="NONE", width=24) -> None:
    """A long text as several labels (a panel label does not wrap)."""
    col = layout.column(align=True)
    line = ""
    for word in text.split():
        if line and len(line) + len(word) > width:
            col.label(text=line, icon=icon)
            icon, line = "BLANK1", ""
        line = f"{line} {word}".strip()
    col.label(text=line, icon=icon)


class VIEW3D_PT_atlas_defrag(_Panel, bpy.types.Panel):
    bl_space_type = "VIEW_3D"


class IMAGE_PT_atlas_defrag(_Panel, bpy.types.Panel):
    bl_space_type = "IMAGE_EDITOR"


class AtlasDefragPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    def draw(self, context):
        problem = operators.native_problem()
        if problem:
            _wrapped(self.layout, problem, icon="ERROR", width=90)
        else:
            self.layout.label(text="Native module loaded: " + operators.native_check.running(), icon="CHECKMARK")


def install_presets() -> None:
    """Writes the shipped presets into the user's preset folder (once: a user's
    edits are kept)."""
    folder = bpy.utils.user_resource("SCRIPTS", path=PRESET_DIR, create=True)
    for name, values in PRESETS.items():
        path = os.path.join(folder, bpy.path.clean_name(name) + ".py")
        if os.path.exists(path):
            continue
        lines = ["import bpy", "op = bpy.context.active_operator"]
        lines += [f"op.{key} = {value!r}" for key, value in values.items()]
        with open(path, "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")


def _say_problem():
    """At enable time, in a window: the native module's problem in a popup."""
    problem = operators.native_problem()
    wm = bpy.context.window_manager
    if problem and wm is not None and wm.windows:
        wm.popup_menu(lambda self, _c: _wrapped(self.layout, problem, width=90),
                      title="Atlas Defrag", icon="ERROR")
    return None


classes = (AtlasDefragSettings, VIEW3D_PT_atlas_defrag, IMAGE_PT_atlas_defrag, AtlasDefragPreferences)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.atlas_defrag = PointerProperty(type=AtlasDefragSettings)
    try:
        install_presets()
    except OSError as exc:  # a read-only user folder: the presets are only missing
        print(f"Atlas Defrag: presets not installed: {exc}")
    problem = operators.native_problem()
    if problem:
        print(problem)
        if not bpy.app.background:
            bpy.app.timers.register(_say_problem, first_interval=0.5)


def unregister():
    del bpy.types.Scene.atlas_defrag
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)
