# SPDX-License-Identifier: MIT
"""The scenarios in the bpy 4.5 module, in process (add-on from the build)."""

from __future__ import annotations

import bpy
import pytest

import bl_scenarios as S

NATIVE_SCENARIOS = ["operator_tetra", "png_read_from_file", "edit_mode_undo", "python_entry", "duplicate_materials_and_removal",
                    "save_beside_blend", "world_scale_density", "cancel_leaves_nothing", "worker_thread_run",
                    "operator_smithsonian", "operator_meshroom", "fbx_round_trip_meshroom",
                    "fbx_round_trip_smithsonian", "obj_round_trip_meshroom", "save_reopen", "several_objects",
                    "several_objects_one_fails", "one_atlas_for_all_selected", "one_atlas_shared_material",
                    "shared_material_one_at_a_time", "quads_stay_whole", "scan_quads_stay_whole",
                    "source_uv_warning_names_rendered_nodes", "default_uv_readers_keep_the_old_map",
                    "long_uv_map_names_fit_the_nodes", "an_image_already_named_as_the_new_one_keeps_its_name",
                    "material_shared_with_an_unselected_object",
                    "operator_takes_what_it_is_told", "image_settings_the_bake_cannot_follow_are_said",
                    "linear_float_images_keep_their_colour_space", "obj_output_names_a_base_colour_behind_a_mix",
                    "linked_duplicate_with_its_own_material_is_named",
                    "images_in_node_groups_keep_the_old_map", "premultiplied_byte_images_keep_their_colours",
                    "a_failed_save_takes_back_its_folders",
                    "an_image_reading_another_map_decides_the_default_map", "an_object_linked_slot_is_not_another_user",
                    "the_base_colours_map_is_the_default_among_several"]


def test_is_blender_4():
    assert bpy.app.version >= (4, 2, 0)


@pytest.mark.parametrize("scenario", NATIVE_SCENARIOS)
def test_bpy45(pkg, native, scenario):
    S.SCENARIOS[scenario](pkg)
