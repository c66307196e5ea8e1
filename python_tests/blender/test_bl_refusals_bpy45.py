# SPDX-License-Identifier: MIT
"""defragment() in bpy 4.5 on what it must refuse (issue 15): linked data,
and arguments whose errors used to escape as TypeError or OSError."""

from __future__ import annotations

import bpy
import pytest

import blhelp as H


@pytest.fixture()
def plane(pkg, native):
    H.reset()
    obj = H.textured_plane()
    H.make_active(obj)
    return obj


def test_library_linked_objects_are_refused_and_left_alone(pkg, native, plane, tmp_path):
    library = tmp_path / "library.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(library))
    H.reset()
    with bpy.data.libraries.load(str(library), link=True) as (source, target):
        target.objects = ["Plane"]
    obj = target.objects[0]
    bpy.context.scene.collection.objects.link(obj)
    H.make_active(obj)
    before = H.object_state(obj.name)
    with pytest.raises(pkg.DefragError, match=r"linked from the library .* make it local"):
        pkg.defragment(obj)
    assert H.object_state(obj.name) == before
    # Made local (object, mesh and materials), it defragments.
    bpy.ops.object.make_local(type="ALL")
    report = pkg.defragment(bpy.context.view_layer.objects.active)
    assert report["charts_after"] >= 1


@pytest.mark.parametrize("options, cause", [
    ({"no_such_option": 1}, None),  # refused by the add-on itself, naming the options it knows
    ({"target_charts": 2 ** 40}, ValueError),
    ({"target_charts": "many"}, ValueError),
    ({"storage": "SAVE", "image_dir": "/proc/atlas_defrag_nowhere"}, OSError),
])
def test_bad_arguments_raise_defrag_error_keeping_the_cause(pkg, native, plane, tmp_path, options, cause):
    if options.get("image_dir", "").startswith("/proc"):
        blocker = tmp_path / "a_file"
        blocker.write_text("x")
        options = dict(options, image_dir=str(blocker / "images"))
    before = H.object_state(plane.name)
    with pytest.raises(pkg.DefragError) as info:
        pkg.defragment(plane, **options)
    if cause is None:
        assert info.value.__cause__ is None and "known: density_loss_budget" in str(info.value), info.value
    else:
        assert isinstance(info.value.__cause__, cause), repr(info.value.__cause__)
    assert "Unable to cast" not in str(info.value)
    assert H.object_state(plane.name) == before
