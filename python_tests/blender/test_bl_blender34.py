# SPDX-License-Identifier: MIT
"""The scenarios in Debian's Blender 3.4 (subprocesses; add-on from the build)."""

from __future__ import annotations

import json

import pytest

import bl_scenarios as S
from blenv import ADDON_PARENT, HERE, require_native, run_blender

# Scenarios run together in one Blender process per group (keeps startup cost low;
# every scenario starts from factory settings).
GROUPS = {
    # redo_asks_first: ed.undo_redo under a window override crashes the bpy 4.5 module.
    "light": ["write_identity_layout", "material_index_past_the_slots_keeps_drawing_with_the_last",
              "linked_duplicate_with_its_own_material_is_named", "png_read_from_file", "redo_asks_first",
              "source_uv_warning_names_rendered_nodes", "default_uv_readers_keep_the_old_map",
              "long_uv_map_names_fit_the_nodes", "an_image_already_named_as_the_new_one_keeps_its_name",
              "material_shared_with_an_unselected_object",
              "operator_takes_what_it_is_told", "image_settings_the_bake_cannot_follow_are_said",
              "linear_float_images_keep_their_colour_space", "obj_output_names_a_base_colour_behind_a_mix",
              "images_in_node_groups_keep_the_old_map", "premultiplied_byte_images_keep_their_colours",
              "a_failed_save_takes_back_its_folders",
              "an_image_reading_another_map_decides_the_default_map", "an_object_linked_slot_is_not_another_user",
              "the_base_colours_map_is_the_default_among_several"]
    + ["error_" + c for c in sorted(S.ERRORS)],
    "tetra": ["operator_tetra", "edit_mode_undo", "python_entry", "duplicate_materials_and_removal",
              "save_beside_blend", "world_scale_density", "cancel_leaves_nothing", "worker_thread_run"],
    "smithsonian": ["operator_smithsonian"],
    "meshroom": ["operator_meshroom"],
    "export": ["fbx_round_trip_meshroom", "fbx_round_trip_smithsonian", "obj_round_trip_meshroom", "save_reopen",
               "several_objects", "several_objects_one_fails", "one_atlas_for_all_selected",
               "one_atlas_shared_material",
               "shared_material_one_at_a_time", "quads_stay_whole", "scan_quads_stay_whole"],
}
NEEDS_NATIVE = {"light", "tetra", "smithsonian", "meshroom", "export"}
_cache = {}


def group_results(group, tmp_path_factory):
    if group not in _cache:
        if group in NEEDS_NATIVE:
            require_native()
        out = tmp_path_factory.mktemp(f"bl34_{group}") / "result.json"
        proc = run_blender(["--python", str(HERE / "bl_runner.py"), "--", "--addon-parent",
                            str(ADDON_PARENT), "--out", str(out)] + GROUPS[group])
        try:
            data = json.loads(out.read_text())
        except (OSError, ValueError):
            data = {"results": {}}
        data["log"] = (proc.stdout[-3000:], proc.stderr[-3000:], proc.returncode)
        _cache[group] = data
    return _cache[group]


CASES = [(g, s) for g, names in GROUPS.items() for s in names]


@pytest.mark.parametrize("group,scenario", CASES, ids=[s for _, s in CASES])
def test_blender34(group, scenario, tmp_path_factory):
    data = group_results(group, tmp_path_factory)
    res = data["results"].get(scenario)
    assert res is not None, f"scenario did not run; Blender log: {data['log']}"
    if "skipped" in res:
        pytest.skip(res["skipped"])
    assert data.get("blender", "").startswith("3."), data.get("blender")
    assert str(ADDON_PARENT) in data.get("package", ""), data.get("package")
    assert res["ok"], res["error"]
