# SPDX-License-Identifier: MIT
"""Finding and driving the tool in the bpy module (4.5, and 5.0 through
test_bl_bpy50.py): menus in Object Mode, the sidebar panel and its settings,
presets, the words of the messages, the dialog's checks, and the message when
the native module is built for another platform (Blender 3.4 too)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import bpy
import pytest

import blhelp as H
import bl_scenarios as S
from blenv import ADDON_PARENT, HERE, run_blender


def test_found_in_object_mode_menus(pkg):
    """Object Mode: Object menu and the UV Editor's Image menu (menu search,
    F3, lists the entries of these menus); Edit Mode: both UV menus."""
    for menu in ("VIEW3D_MT_object", "IMAGE_MT_image", "IMAGE_MT_uvs", "VIEW3D_MT_uv_map"):
        funcs = getattr(bpy.types, menu)._dyn_ui_initialize()
        assert pkg.operators.menu_func in funcs, menu
    assert "defrag" in bpy.ops.uv.defragment_atlas.get_rna_type().name.lower()


def test_tooltip_and_properties(pkg):
    rna = bpy.ops.uv.defragment_atlas.get_rna_type()
    assert "\n" not in rna.description and "  " not in rna.description, repr(rna.description)
    assert "use_modal" not in rna.properties.keys()  # nothing internal on the Info line
    assert rna.properties["new_map_first"].default is True


def test_panel_settings_match_the_operator(pkg):
    for name in ("VIEW3D_PT_atlas_defrag", "IMAGE_PT_atlas_defrag"):
        panel = getattr(bpy.types, name)
        assert panel.bl_region_type == "UI" and panel.bl_category == "Atlas Defrag", name
    H.reset()
    settings = bpy.context.scene.atlas_defrag
    op = bpy.ops.uv.defragment_atlas.get_rna_type().properties
    for name in pkg.operators.setting_names():
        assert getattr(settings, name) == op[name].default, name


def test_presets_are_installed_and_name_real_properties(pkg):
    folder = bpy.utils.user_resource("SCRIPTS", path=pkg.ui.PRESET_DIR)
    names = set(pkg.operators.setting_names())
    for preset, values in pkg.ui.PRESETS.items():
        path = os.path.join(folder, bpy.path.clean_name(preset) + ".py")
        assert os.path.isfile(path), path
        assert set(values) <= names, set(values) - names

        class Op:  # what a preset file sees as bpy.context.active_operator
            pass
        op = Op()
        code = open(path).read().replace("bpy.context.active_operator", "op")
        exec(compile(code, path, "exec"), {"op": op, "bpy": bpy})
        assert vars(op) == values, (preset, vars(op))


def test_messages_use_the_dialog_names(pkg):
    H.reset()
    H.textured_plane()
    with pytest.raises(RuntimeError) as err:
        bpy.ops.uv.defragment_atlas(automatic_fixed_page_size=False, fixed_page_size=8192, max_page_size=4096)
    msg = str(err.value)
    assert "'Page Size' 8192 is larger than 'Maximum Page Size' 4096" in msg, msg
    assert "fixed_page_size" not in msg


def test_dialog_refuses_before_it_opens(pkg):
    """A mesh without image texture: INVOKE fails at once, no dialog."""
    S.make_error_case("no_image_texture")
    with pytest.raises(RuntimeError, match="No image texture"):
        bpy.ops.uv.defragment_atlas("INVOKE_DEFAULT")


def test_stop_reasons_in_words(pkg):
    text = pkg.operators.stop_text({"aggregate_stops": {"not_disk": 3, "feasible": 1, "non_manifold": 0}})
    assert text.startswith("Adjacent charts left apart because 3 pairs: the merged chart would have a hole")
    assert "1 pair: nothing refused them: the Target Charts count was reached first" in text
    assert "non-manifold" not in text
    assert pkg.operators.stop_text({"aggregate_stops": {"not_disk": 0}}) == ""


def test_image_editor_shows_the_new_image(pkg, native):
    H.reset()
    obj = H.import_model(H.model_path("tetra"))
    area = bpy.context.window_manager.windows[0].screen.areas[0]
    area.type = "IMAGE_EDITOR"
    area.spaces.active.image = bpy.data.images["textured_0_v2.jpg"]
    report = pkg.defragment(obj)

    class Context:
        screen = bpy.context.window_manager.windows[0].screen
    pkg.operators.show_in_image_editors(Context, [report])
    assert area.spaces.active.image.name == "textured_0_v2_defrag"


def _hidden_native_copy(tmp_path):
    """The built package with its module replaced by one for Windows, Python 3.10."""
    parent = tmp_path / "addon"
    shutil.copytree(ADDON_PARENT / "atlas_defrag", parent / "atlas_defrag")
    for f in (parent / "atlas_defrag").glob("_native*"):
        f.unlink()
    (parent / "atlas_defrag" / "_native.cp310-win_amd64.pyd").write_bytes(b"")
    return parent


def _check_hidden(res):
    for text in (res["problem"], res["error"]):
        assert "built for windows-x64, Python 3.10" in text and "linux-x64, Python 3.11" in text, text
    assert res["poll"] is False


def test_missing_native_module_says_which_platform(tmp_path):
    parent = _hidden_native_copy(tmp_path)
    out = tmp_path / "res.json"
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)
    proc = subprocess.run([sys.executable, str(HERE / "bl_hidden_native.py"), str(parent), str(out)],
                          capture_output=True, text=True, timeout=300, env=env)
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "built for windows-x64" in proc.stdout, proc.stdout[-2000:]  # said at enable time
    _check_hidden(json.loads(out.read_text()))


def test_missing_native_module_blender34(tmp_path):
    parent = _hidden_native_copy(tmp_path)
    out = tmp_path / "res.json"
    proc = run_blender(["--python", str(HERE / "bl_hidden_native.py"), "--", str(parent), str(out)], timeout=300)
    assert out.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    res = json.loads(out.read_text())
    assert res["blender"].startswith("3."), res
    _check_hidden(res)
