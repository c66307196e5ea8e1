"""The command-line entry, tools/defrag_scan.py, run as users run it: on a real
scan, without Blender, and its output read back from disk."""
import errno
import os
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

CLI = Path(__file__).resolve().parent.parent / "tools" / "defrag_scan.py"


def test_cli_runs_from_a_checkout_without_pythonpath_and_refuses_formats_it_cannot_read(tmp_path):
    """As a newcomer types it; an extension it cannot read is a usage error
    (exit 2), as in the batch entry."""
    repo = CLI.parent.parent
    if Path(os.environ.get("ATLAS_BUILD_DIR", repo / "build")) != repo / "build":
        pytest.skip("the fallback finds the checkout's own build/ only")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    run = subprocess.run([sys.executable, str(CLI), "--help"], capture_output=True, text=True, timeout=60, env=env)
    assert run.returncode == 0 and "_defrag_page<P>_<map>.png" in run.stdout, run.stderr
    run = subprocess.run([sys.executable, str(CLI), str(tmp_path / "m.fbx"), str(tmp_path)], capture_output=True,
                         text=True, timeout=60, env=env)
    assert run.returncode == 2 and "unsupported scan format '.fbx'" in run.stderr, run.stderr


def test_cli_output_loads_back_flip_free_with_the_colours_kept(native, scans, scan_path, tool_env, tmp_path):
    import scan_io

    source = scan_path("tetra")
    run = subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path), "--metrics"],
                         capture_output=True, text=True, timeout=300, env=tool_env)
    assert run.returncode == 0, run.stderr
    assert "159 -> " in run.stdout and "PSNR" in run.stdout
    assert re.search(r"lone charts overlapping themselves halved: \d+;", run.stdout), run.stdout

    scan, written = scans("tetra"), scan_io.load(tmp_path / f"{source.stem}_defrag.obj")
    assert np.array_equal(written.triangles, scan.triangles)
    assert np.allclose(written.positions, scan.positions, rtol=1e-8, atol=1e-12)  # written with 9 digits
    assert (written.face_page >= 0).all() and len(written.page_images) >= 1
    m = native.measure(scan.positions, scan.triangles, scan.uvs, scan.face_page, scan.page_sizes,
                       written.uvs, written.face_page, written.page_sizes)
    assert m["new"]["flipped_faces"] == 0 and m["new"]["overlap_texels"] == 0
    # Every corner keeps the shading normal it was read with (the faces are grouped by page when written).
    assert np.array_equal(written.normals[written.normal_index], scan.normals[scan.normal_index])
    # Through the PNG files: rows upside down or channels mixed would not pass.
    old = [np.ascontiguousarray(scan_io.load_image(p)[:, :, :3]) for p in scan.page_images]
    new = [np.ascontiguousarray(scan_io.load_image(p)[:, :, :3]) for p in written.page_images]
    fidelity = native.compare_colors(scan.positions, scan.triangles, scan.uvs, scan.face_page, old,
                                     written.uvs, written.face_page, new, samples=100000)
    assert fidelity["psnr_db"] > 38


def test_obj_reader_triangulates_polygons_and_resolves_relative_indices(native, tmp_path):
    path = tmp_path / "quad.obj"
    path.write_text("mtllib a b.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0 0.5 0.5 0.5\n"
                    "vt 0 0\nvt 1 0\nvt 1 1 0\nvt 0 1\nusemtl first\nf 1/1 2/2 3/3 4/4\n"
                    "usemtl second one\nf -4/-4/1 -2/-2/1 -1/-1/1\nf 1//1 2//1 3//1  # no UVs\nf 1 2\n")
    obj = native.read_obj(str(path))
    assert obj["triangles"].tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3], [0, 1, 2]]
    assert obj["texcoord_index"].tolist() == [[0, 1, 2], [0, 2, 3], [0, 2, 3], [-1, -1, -1]]
    assert obj["face_material"].tolist() == [0, 0, 1, 1]
    assert obj["materials"] == ["first", "second one"] and obj["material_libraries"] == ["a b.mtl"]
    assert obj["positions"].shape == (4, 3) and obj["texcoords"][2].tolist() == [1.0, 1.0]
    assert obj["normals"].shape == (0, 3) and (obj["normal_index"] == -1).all()


def test_obj_normals_are_read_per_corner_and_written_back(native, tmp_path):
    """vn lines are kept through triangulation (a face missing one on any
    corner has none) and written back exactly, each face naming its own."""
    path = tmp_path / "shaded.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nvn 0.1 0.2 0.9746794344808963\n"
                    "f 1/1/1 2/1/2 3/1/1 4/1/2\nf 1//2 3//1 4\nf 1//3 2//1 3//1\nvn 0 1 0\n")
    obj = native.read_obj(str(path))  # the last face names a normal defined only after it: none
    assert obj["normal_index"].tolist() == [[0, 1, 0], [0, 0, 1], [-1, -1, -1], [-1, -1, -1]]
    obj["triangles"], obj["normal_index"] = obj["triangles"][:3], obj["normal_index"][:3]
    out = tmp_path / "out.obj"
    native.write_obj(str(out), "out.mtl", obj["positions"], obj["triangles"], np.zeros((3, 3, 2)),
                     np.zeros(3, np.int64), ["m"], obj["normals"], obj["normal_index"])
    back = native.read_obj(str(out))
    assert np.array_equal(back["normals"], obj["normals"])
    assert np.array_equal(back["normal_index"], obj["normal_index"])
    with pytest.raises(ValueError, match="together"):
        native.write_obj(str(out), "out.mtl", obj["positions"], obj["triangles"], np.zeros((3, 3, 2)),
                         np.zeros(3, np.int64), ["m"], obj["normals"], None)


def test_obj_reader_clips_a_concave_polygon_into_ears(native, tmp_path):
    """An arrow-tail hexagon, tilted out of every axis plane, notched at
    (1, 0.5): a fan from (2, 2), its first corner, would cover the notch and
    fold over (Blender's limited dissolve writes such n-gons)."""
    outline = np.array([[0, -0.2], [2, -1], [1, 0.5], [2, 2], [0, 1.2], [-1, 0.5]], float)
    outline = np.roll(outline, -3, axis=0)
    tilt = np.array([[0.8, 0.0, 0.6], [0.36, 0.8, -0.48]])
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in outline @ tilt]
    lines += [f"vt {u / 4 + 0.3:.6f} {v / 4 + 0.3:.6f}" for u, v in outline]
    path = tmp_path / "concave.obj"
    path.write_text("\n".join(lines) + "\nf 1/1 2/2 3/3 4/4 5/5 6/6\n")
    obj = native.read_obj(str(path))
    corners = obj["texcoords"][obj["texcoord_index"]]
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    areas = 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    x, y = outline[:, 0], outline[:, 1]
    polygon_area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))) / 16
    assert len(areas) == 4 and (areas > 0).all()
    assert abs(areas.sum() - polygon_area) < 1e-9


def test_obj_reader_names_the_line_of_a_bad_index_or_number(native, tmp_path):
    import pytest

    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 4\n")
    with pytest.raises(ValueError, match="line 4: vertex index 4"):
        native.read_obj(str(path))
    path.write_text("v 0 0 x\n")
    with pytest.raises(ValueError, match="line 1: expected a number"):
        native.read_obj(str(path))
    with pytest.raises(FileNotFoundError, match="missing.obj"):  # an OSError, as write_obj's failures are
        native.read_obj(str(tmp_path / "missing.obj"))


def test_gltf_with_files_beside_it_reads_as_the_glb(scans, scan_path, tmp_path):
    """The Smithsonian GLB split into .gltf + .bin + image files reads back the same."""
    import json
    import struct

    import scan_io

    data = scan_path("smithsonian").read_bytes()
    json_len = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + json_len])
    binary = data[28 + json_len:28 + json_len + struct.unpack_from("<I", data, 20 + json_len)[0]]
    for i, image in enumerate(gltf["images"]):
        view = gltf["bufferViews"][image.pop("bufferView")]
        start = view.get("byteOffset", 0)
        (tmp_path / f"image {i}.png").write_bytes(binary[start:start + view["byteLength"]])
        image["uri"] = f"image%20{i}.png"
    (tmp_path / "scan.bin").write_bytes(binary)
    gltf["buffers"][0]["uri"] = "scan.bin"
    (tmp_path / "scan.gltf").write_text(json.dumps(gltf))

    glb, split = scans("smithsonian"), scan_io.load(tmp_path / "scan.gltf")
    for name in ("positions", "triangles", "uvs", "face_page", "page_sizes"):
        assert np.array_equal(getattr(split, name), getattr(glb, name)), name
    assert [sorted(m) for m in split.maps] == [sorted(m) for m in glb.maps]
    assert all(split.maps[0][role] == glb.maps[0][role] for role in glb.maps[0])


def test_cli_without_metrics_writes_the_same_files(scan_path, tool_env, tmp_path):
    source = scan_path("tetra")
    runs = [subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path / name), *flags],
                           capture_output=True, text=True, timeout=300, env=tool_env)
            for name, flags in (("full", ["--metrics"]), ("quick", []))]
    assert all(r.returncode == 0 for r in runs), [r.stderr for r in runs]
    assert "PSNR" in runs[0].stdout and "PSNR" not in runs[1].stdout and "charts" in runs[1].stdout
    full, quick = sorted((tmp_path / "full").iterdir()), sorted((tmp_path / "quick").iterdir())
    assert [f.name for f in full] == [f.name for f in quick]
    assert all(a.read_bytes() == b.read_bytes() for a, b in zip(full, quick))


def _one_triangle_gltf(tmp_path, name, **changes):
    """A .gltf of one triangle (positions in a data: URI, no indices, no
    texture), with top-level fields replaced by `changes`."""
    import base64
    import json

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32).tobytes()
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
            "bufferViews": [{"buffer": 0, "byteLength": len(positions)}],
            "buffers": [{"byteLength": len(positions),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(positions).decode()}]}
    gltf.update(changes)
    path = tmp_path / name
    path.write_text(json.dumps(gltf))
    return path


def test_obj_normals_that_are_no_vectors_leave_their_faces_without(native, tmp_path):
    """A vn line of two values, or one an old exporter wrote as 1.#QNAN0,
    refuses no scan: the faces naming it get no normals."""
    path = tmp_path / "odd.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0\nvn 1.#QNAN0 0 1\nvn 0 0 1\n"
                    "f 1//1 2//3 3//3\nf 1//2 2//3 3//3\nf 1//3 2//3 3//3\n")
    obj = native.read_obj(str(path))
    assert obj["normal_index"].tolist() == [[-1, -1, -1], [-1, -1, -1], [2, 2, 2]]


def test_gltf_normals_turn_with_their_node(tmp_path):
    """NORMALs go into the scene's frame by the inverse transpose of the
    node's matrix, unit again: under a shear they stay perpendicular to the
    triangle."""
    import base64

    import scan_io

    data = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 1], [0, 0, 1]], np.float32).tobytes()
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    shear = [1, 0, 0, 0, 0.5, 2, 0, 0, 0, 0, 3, 0, 0, 0, 0, 1]  # column-major: y -> (0.5, 2, 0), z scaled 3
    path = _one_triangle_gltf(
        tmp_path, "sheared.gltf", nodes=[{"mesh": 0, "matrix": shear}],
        meshes=[{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}}]}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                   {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3"}],
        bufferViews=[{"buffer": 0, "byteLength": len(data)}], buffers=[{"byteLength": len(data), "uri": uri}])
    scan = scan_io.load(path)
    p = scan.positions[scan.triangles[0]]
    n = scan.normals[scan.normal_index[0]]
    assert np.allclose(np.linalg.norm(n, axis=1), 1)
    assert np.allclose(n @ (p[1] - p[0]), 0) and np.allclose(n @ (p[2] - p[0]), 0)
    assert (n @ np.cross(p[1] - p[0], p[2] - p[0]) > 0).all()  # still on the front side
    assert _one_triangle_gltf(tmp_path, "bare.gltf").exists() and scan_io.load(tmp_path / "bare.gltf").normals is None
    short = _one_triangle_gltf(
        tmp_path, "short.gltf", meshes=[{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}}]}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                   {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 2, "type": "VEC3"}],
        bufferViews=[{"buffer": 0, "byteLength": len(data)}], buffers=[{"byteLength": len(data), "uri": uri}])
    with pytest.raises(ValueError, match="2 NORMALs for 3 POSITIONs"):
        scan_io.load(short)


def test_gltf_without_scenes_walks_its_node_trees_from_their_roots(tmp_path):
    """`scenes` is optional: the roots are then the nodes no node names as a
    child (each child was reached twice before, and the file refused)."""
    import scan_io

    path = _one_triangle_gltf(tmp_path, "loose.gltf", scenes=[], nodes=[{"children": [1]}, {"mesh": 0}])
    assert scan_io.load(path).triangles.tolist() == [[0, 1, 2]]


@pytest.mark.parametrize("name", ["cut.glb", "cut.gltf"])
def test_gltf_json_cut_short_is_refused_in_words(tmp_path, name):
    import scan_io

    text = _one_triangle_gltf(tmp_path, "plain.gltf").read_bytes()[:-9]
    path = tmp_path / name
    glb = struct.pack("<III", 0x46546C67, 2, 20 + len(text)) + struct.pack("<II", len(text), 0x4E4F534A)
    path.write_bytes(glb + text if name.endswith(".glb") else text)
    with pytest.raises(ValueError, match="^malformed glTF .its JSON part is not valid UTF-8 JSON: "):
        scan_io.load(path)


def test_glb_cut_short_is_refused_in_words(scan_path, tmp_path):
    """A GLB whose download or copy stopped: its header gives the whole
    length, which says so before any chunk is read."""
    import scan_io

    data = scan_path("smithsonian").read_bytes()
    path = tmp_path / "cut.glb"
    path.write_bytes(data[:len(data) * 6 // 10])
    with pytest.raises(ValueError, match=f"^the file is cut short: its header gives {len(data):,} bytes and it holds "):
        scan_io.load(path)


def test_an_embedded_map_that_cannot_be_decoded_is_named(tmp_path):
    """Pillow names only its stream object for bytes it cannot identify: the
    message names the map and says what is wrong."""
    import defrag_scan
    import scan_io

    with pytest.raises(defrag_scan.job.DefragError, match="^cannot read the texture page0_normal .embedded.: "
                       "the image's bytes are in no image format this reader decodes"):
        defrag_scan.read_texture(scan_io.image_size, b"not an image at all", "page0_normal (embedded)")


def test_gltf_json_nested_too_deeply_is_refused_in_words(tmp_path):
    import scan_io

    path = tmp_path / "deep.gltf"
    path.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(ValueError, match="nests too deeply"):
        scan_io.load(path)


def test_gltf_image_that_cannot_be_decoded_is_named(tmp_path):
    import json

    import scan_io

    path = _textured_triangle_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                   {"source": 0})
    gltf = json.loads(path.read_text())
    gltf["images"] = [{"uri": "my%20tex.png"}]
    path.write_text(json.dumps(gltf))
    (tmp_path / "my tex.png").write_bytes(b"not a PNG at all")
    with pytest.raises(ValueError, match="^its my tex.png is in no image format this reader decodes$"):
        scan_io.load(path)


def test_gltf_primitive_without_indices_reads_its_vertices_in_order(tmp_path):
    import scan_io

    scan = scan_io.load(_one_triangle_gltf(tmp_path, "plain.gltf"))
    assert scan.triangles.tolist() == [[0, 1, 2]]
    assert scan.face_page.tolist() == [-1]


@pytest.mark.parametrize("changes,message", [
    ({"nodes": [{"mesh": 0, "children": [1]}, {"children": [0]}]}, "node 0 is reached twice"),
    ({"nodes": [{"children": [1, 1]}, {"mesh": 0}]}, "node 1 is reached twice"),
    ({"nodes": [{"mesh": -1}]}, "mesh index -1 is out of range"),
    ({"asset": {"version": "1.0"}}, "not a glTF 2.0 file"),
    ({"extensionsRequired": ["KHR_draco_mesh_compression"]}, "KHR_draco_mesh_compression"),
    ({"buffers": [{"byteLength": 36, "uri": "missing.bin"}]}, "cannot be read"),
    ({"accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "MAT9"}]}, "malformed glTF"),
    ({"scenes": [{}]}, "no triangle mesh"),
    ({"extensionsRequired": ["EXT_nonexistent"]}, "uses EXT_nonexistent, which this reader does not support"),
    ({"asset": "2.0"}, "not a glTF 2.0 file"),
    ({"extensionsRequired": 5}, "extensionsRequired is not a list of names"),
    ({"extensionsUsed": None}, "extensionsUsed is not a list of names"),
    # The buffer holds the 36 bytes the accessor reads, its view only 24.
    ({"bufferViews": [{"buffer": 0, "byteLength": 24}]}, "reads 36 bytes of bufferView 0, which holds 24"),
    ({"buffers": [{"byteLength": 36, "uri": "pipe.bin"}]}, "pipe.bin is not a regular file"),
    # A texture transform its writer did not list in extensionsUsed.
    ({"materials": [{"pbrMetallicRoughness": {"baseColorTexture": {
        "index": 0, "extensions": {"KHR_texture_transform": {"scale": [2, 2]}}}}}]},
     "uses KHR_texture_transform, which this reader does not support"),
])
def test_cli_names_what_is_wrong_with_a_bad_gltf(tool_env, tmp_path, changes, message):
    """Bad files end in one line on stderr and exit code 1, not a traceback
    (and a node hierarchy with a cycle, or a FIFO as buffer, does not hang the reader)."""
    os.mkfifo(tmp_path / "pipe.bin")
    path = _one_triangle_gltf(tmp_path, "bad.gltf", **changes)
    proc = subprocess.run([sys.executable, str(CLI), str(path), str(tmp_path / "out")], env=tool_env,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1, proc.stderr
    assert "Traceback" not in proc.stderr and message in proc.stderr, proc.stderr
    assert proc.stderr.startswith("defrag_scan: error: cannot read"), proc.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("changes, triangles", [
    ({}, [[0, 1, 2]]),
    ({"nodes": [{"mesh": 0, "scale": [-1, 1, 1]}]}, [[2, 1, 0]]),  # mirrored: the winding turns round
    ({"meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 5}]}]}, [[0, 1, 2]]),  # a strip
])
def test_gltf_triangles_as_the_primitive_and_its_node_give_them(tmp_path, changes, triangles):
    import scan_io

    assert scan_io.load(_one_triangle_gltf(tmp_path, "t.gltf", **changes)).triangles.tolist() == triangles


def test_gltf_strips_keep_one_winding_and_drop_their_joins(tmp_path):
    """A strip of two quads joined by a degenerate pair: every other
    triangle's first two corners swap, and the joins are dropped."""
    import base64

    import scan_io

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0], [1, 2, 0]], np.float32).tobytes()
    indices = np.array([0, 1, 2, 3, 3, 2, 2, 3, 4, 5], np.uint16).tobytes()
    data = positions + indices
    path = _one_triangle_gltf(
        tmp_path, "strip.gltf",
        meshes=[{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 5}]}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 6, "type": "VEC3"},
                   {"bufferView": 1, "componentType": 5123, "count": 10, "type": "SCALAR"}],
        bufferViews=[{"buffer": 0, "byteLength": 72}, {"buffer": 0, "byteOffset": 72, "byteLength": 20}],
        buffers=[{"byteLength": len(data), "uri": "data:;base64," + base64.b64encode(data).decode()}])
    assert scan_io.load(path).triangles.tolist() == [[0, 1, 2], [2, 1, 3], [2, 3, 4], [4, 3, 5]]


def test_gltf_fans_turn_round_their_first_vertex(tmp_path):
    """A fan of five vertices: three triangles, each from vertex 0."""
    import base64

    import scan_io

    data = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 1, 0]], np.float32).tobytes()
    path = _one_triangle_gltf(
        tmp_path, "fan.gltf", meshes=[{"primitives": [{"attributes": {"POSITION": 0}, "mode": 6}]}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 5, "type": "VEC3"}],
        bufferViews=[{"buffer": 0, "byteLength": len(data)}],
        buffers=[{"byteLength": len(data), "uri": "data:;base64," + base64.b64encode(data).decode()}])
    assert scan_io.load(path).triangles.tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4]]


def test_gltf_sparse_accessors_are_applied(tmp_path):
    """A sparse accessor without a buffer view: zeros, then its substitutions."""
    import base64

    import scan_io

    positions = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32).tobytes()
    sparse = np.array([1], np.uint16).tobytes() + b"\0\0" + np.array([[5, 0, 0]], np.float32).tobytes()
    data = positions + sparse
    path = _one_triangle_gltf(
        tmp_path, "sparse.gltf",
        accessors=[{"componentType": 5126, "count": 3, "type": "VEC3",
                    "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5123},
                               "values": {"bufferView": 1, "byteOffset": 4}}}],
        bufferViews=[{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 16}],
        buffers=[{"byteLength": len(data), "uri": "data:;base64," + base64.b64encode(data).decode()}])
    assert scan_io.load(path).positions.tolist() == [[0, 0, 0], [5, 0, 0], [0, 0, 0]]


def _textured_triangle_gltf(tmp_path, material: dict, texture: dict, uvs=((0, 0), (1, 0), (0, 1)), **changes):
    """One triangle with these UVs, the given material and texture, and
    top-level fields replaced by `changes`; image 0 a 6 x 4 WebP."""
    import base64
    import io

    from PIL import Image

    webp = io.BytesIO()
    Image.new("RGB", (6, 4), (200, 100, 50)).save(webp, "WEBP")
    data = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes() + \
        np.array(uvs, np.float32).tobytes()
    return _one_triangle_gltf(
        tmp_path, "textured.gltf",
        meshes=[{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": 0}]}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
                   {"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC2"}],
        bufferViews=[{"buffer": 0, "byteLength": len(data)}],
        buffers=[{"byteLength": len(data), "uri": "data:;base64," + base64.b64encode(data).decode()}],
        materials=[material], textures=[texture],
        images=[{"uri": "data:image/webp;base64," + base64.b64encode(webp.getvalue()).decode()}], **changes)


def test_gltf_materials_naming_the_same_images_share_one_page(tmp_path):
    """Two materials on one texture make one page, as two OBJ materials naming
    one file do; a third with another normal map makes a page of its own."""
    import json

    import scan_io

    colour = {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}
    path = _textured_triangle_gltf(tmp_path, colour, {"source": 0})
    gltf = json.loads(path.read_text())
    primitive = gltf["meshes"][0]["primitives"][0]
    gltf["meshes"][0]["primitives"] = [dict(primitive, material=m) for m in range(3)]
    gltf["materials"] = [colour, dict(colour, name="same"), dict(colour, normalTexture={"index": 1})]
    gltf["textures"].append({"source": 0, "sampler": 0})
    gltf["samplers"] = [{}]
    path.write_text(json.dumps(gltf))
    scan = scan_io.load(path)
    assert scan.face_page.tolist() == [0, 0, 1] and len(scan.page_images) == 2


def test_gltf_map_whose_file_is_missing_is_left_out_with_a_warning(tmp_path):
    """As the OBJ reader does: the colour still bakes."""
    import json

    import scan_io

    colour = {"name": "skin", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
              "normalTexture": {"index": 1}}
    path = _textured_triangle_gltf(tmp_path, colour, {"source": 0})
    gltf = json.loads(path.read_text())
    gltf["textures"].append({"source": 1})
    gltf["images"].append({"uri": "gone%20normal.png"})
    path.write_text(json.dumps(gltf))
    scan = scan_io.load(path)
    assert list(scan.maps[0]) == ["base_color"] and scan.face_page.tolist() == [0]
    assert scan.warnings == [f"normal map {tmp_path / 'gone normal.png'} of material 'skin' not found: left out"]


@pytest.mark.parametrize("wrap, uvs, warned", [
    (33071, ((0, 0), (1, 0), (0, 1.00001)), False),  # clamped, within the page up to round-off
    (33071, ((0, 0), (1, 0), (0, 1.5)), True),
    (33648, ((-0.2, 0), (1, 0), (0, 1)), True),      # mirrored
    (10497, ((0, 0), (1, 0), (0, 1.5)), False)])     # repeated, as the bake does
def test_gltf_sampler_that_does_not_repeat_is_warned_of_where_faces_leave_the_page(tmp_path, wrap, uvs, warned):
    import scan_io

    path = _textured_triangle_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                   {"source": 0, "sampler": 0}, uvs, samplers=[{"wrapS": wrap, "wrapT": wrap}])
    assert any("clamps or mirrors" in w for w in scan_io.load(path).warnings) == warned


def test_gltf_diffuse_texture_and_webp_images_are_read(tmp_path):
    """Specular-glossiness materials give their diffuse texture, EXT_texture_webp its image."""
    import scan_io

    spec_gloss = {"extensions": {"KHR_materials_pbrSpecularGlossiness": {"diffuseTexture": {"index": 0}}}}
    scan = scan_io.load(_textured_triangle_gltf(tmp_path, spec_gloss, {"extensions": {"EXT_texture_webp": {"source": 0}}}))
    assert scan.face_page.tolist() == [0] and scan.page_sizes.tolist() == [[6, 4]]
    assert scan_io.load_image(scan.page_images[0])[0, 0].tolist() == pytest.approx([200, 100, 50], abs=8)
    ktx2_only = {"extensions": {"KHR_texture_basisu": {"source": 0}}}
    with pytest.raises(ValueError, match="no image this reader can decode .KHR_texture_basisu"):
        scan_io.load(_textured_triangle_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                             ktx2_only))


def test_cli_names_an_emission_map_and_warns_of_a_metallic_roughness_one(tmp_path, tool_env):
    """An MTL names emission (map_Ke), and has no statement for a map of two
    packed channels: that one is written all the same, and the run says so."""
    material = {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicRoughnessTexture": {"index": 0}},
                "emissiveTexture": {"index": 0}}
    source = _textured_triangle_gltf(tmp_path, material, {"extensions": {"EXT_texture_webp": {"source": 0}}})
    run = subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path / "out")], capture_output=True,
                         text=True, timeout=300, env=tool_env)
    assert run.returncode == 0, run.stderr
    mtl = (tmp_path / "out" / "textured_defrag.mtl").read_text()
    assert "map_Ke textured_defrag_page0_emission.png" in mtl and "metallic" not in mtl, mtl
    assert "textured_defrag_page0_metallic_roughness.png written, but the MTL does not name" in run.stderr
    assert (tmp_path / "out" / "textured_defrag_page0_metallic_roughness.png").is_file()


@pytest.mark.parametrize("mode", ["L", "I;16"])
def test_grey_images_load_as_one_channel(mode):
    """8-bit grey as it is; 16-bit grey scaled to 8 bits (Pillow's own
    conversion to RGB would clip it to white)."""
    import io

    import scan_io
    from PIL import Image

    grey = np.arange(64 * 48, dtype=np.uint16).reshape(48, 64) * 21
    image = Image.fromarray((grey >> 8).astype(np.uint8) if mode == "L" else grey)
    buf = io.BytesIO()
    image.save(buf, "PNG")
    assert Image.open(io.BytesIO(buf.getvalue())).mode == mode
    pixels = scan_io.load_image(buf.getvalue())
    assert pixels.shape == (48, 64, 1) and pixels.dtype == np.uint8
    assert np.array_equal(pixels[::-1, :, 0], grey >> 8)


@pytest.mark.parametrize("mode, transparency", [("RGB", None), ("RGBA", None), ("RGB", (1, 2, 3)), ("P", 0)])
def test_png_images_load_as_pillow_reads_them(mode, transparency):
    """RGB and RGBA PNGs go through the add-on's decoder, a PNG with a tRNS
    chunk (which it refuses) through Pillow: the same pixels either way, row 0
    at the bottom, and a tRNS chunk gives alpha, as in Blender (a palette
    entry or a colour made transparent)."""
    import io

    import scan_io
    from atlas_defrag import png_files
    from PIL import Image

    rng = np.random.default_rng(7)
    pixels = rng.integers(0, 256, size=(37, 53, 3 if mode == "P" else len(mode)), dtype=np.uint8)
    pixels[0, 0, :3] = (1, 2, 3)  # the colour key, or (after quantizing) palette entry 0
    image = Image.fromarray(pixels)
    if mode == "P":
        image = image.quantize(8)
        pixels = np.asarray(image.convert("RGB"))
        transparency = int(np.asarray(image)[0, 0])
    buf = io.BytesIO()
    image.save(buf, "PNG", **({"transparency": transparency} if transparency is not None else {}))
    data = buf.getvalue()
    assert (b"tRNS" in data) == (transparency is not None)
    if transparency is not None:
        with pytest.raises(ValueError):
            png_files.decode_png(data)
        keyed = np.all(pixels == pixels[0, 0], axis=2)
        pixels = np.dstack([pixels, np.where(keyed, 0, 255).astype(np.uint8)])
    loaded = scan_io.load_image(data)
    assert loaded.shape == pixels.shape and np.array_equal(loaded[::-1], pixels)


def _two_material_obj(folder: Path, mtl: str, mtllib: str = "m.mtl", textures=("t0.png", "t1.png")) -> Path:
    """Two unit squares, material a on the first and b on the second, the
    MTL text as given, and 8 x 8 PNGs of the given names (red, then blue)."""
    from atlas_defrag import png_files

    folder.mkdir(parents=True, exist_ok=True)
    for name, colour in zip(textures, ((200, 0, 0), (0, 0, 200))):
        if name:
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            (folder / name).write_bytes(png_files.encode_png(np.full((8, 8, 3), colour, np.uint8)))
    (folder / (mtllib.strip('"') if mtllib.startswith('"') else mtllib.split()[-1])).write_text(mtl, encoding="utf-8")
    (folder / "m.obj").write_text(
        f"mtllib {mtllib}\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
        "vt 0.1 0.1\nvt 0.9 0.1\nvt 0.9 0.9\nvt 0.1 0.9\n"
        "usemtl a\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\nusemtl b\nf 2/1 5/2 6/3\nf 2/1 6/3 3/4\n")
    return folder / "m.obj"


@pytest.mark.parametrize("mtl, mtllib, textures", [
    ("newmtl a\nmap_Kd -s 1 1 1 my t0.png\nnewmtl b\nmap_Kd t1.png # diffuse\n", "m.mtl", ("my t0.png", "t1.png")),
    ("\ufeffnewmtl a\nmap_kd t0.png\nnewmtl b\nmap_Kd C:\\scans\\t1.png\n", "m.mtl", ("t0.png", "t1.png")),
    ("newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd C:\\scans\\job\\maps\\t1.png\n", "m.mtl", ("t0.png", "maps/t1.png")),
    ("newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n", "mat/m.mtl", ("mat/t0.png", "t1.png")),
    ('newmtl a\nmap_Kd -bm 1 "my t0.png"\nnewmtl b\nmap_Kd "t1.png"\n', '"my m.mtl"', ("my t0.png", "t1.png")),
])
def test_mtl_textures_are_found_as_writers_name_them(tmp_path, mtl, mtllib, textures):
    """Names with spaces after options, a trailing comment, a byte-order
    mark, lower-case keywords, a path from another machine (its file beside
    the MTL, or in the folder the path ends in), a texture beside an MTL in
    a subfolder, names in quotes (Blender reads them)."""
    import scan_io

    scan = scan_io.load(_two_material_obj(tmp_path, mtl, mtllib, textures))
    assert scan.face_page.tolist() == [0, 0, 1, 1] and not scan.warnings, scan.warnings
    assert [p.name for p in scan.page_images] == [Path(t).name for t in textures]


def test_obj_reader_takes_what_writers_write(native, tmp_path):
    """`#` inside material and library names (3ds Max's "Material #25", as
    Blender reads them) but a comment after numbers, `vt u` without v, a line
    continued by a backslash, \\r, \\r\\n and \\n line ends in one file, and
    colours after a vertex (MeshLab's `v x y z r g b`)."""
    path = tmp_path / "m.obj"
    path.write_bytes(b"mtllib scan#2.mtl\r\nv 0 0 0 0.5 0.5 0.5\rv 1 0 0 # a comment\nv 1 1 0\n"
                     b"vt 0.25\nvt 1 0\nvt 1 1\nusemtl Material #25\nf 1/1 2/2 \\\n  3/3\n")
    obj = native.read_obj(str(path))
    assert obj["materials"] == ["Material #25"] and obj["material_libraries"] == ["scan#2.mtl"]
    assert obj["texcoords"].tolist() == [[0.25, 0], [1, 0], [1, 1]]
    assert obj["triangles"].tolist() == [[0, 1, 2]] and obj["positions"][1].tolist() == [1, 0, 0]
    assert obj["vertex_colours"]
    path.write_bytes(b"v 0 0 0\nv 1 0 0 1\nv 1 1 0\nf 1 2 3\n")  # x y z w: no colour
    assert not native.read_obj(str(path))["vertex_colours"]


def test_obj_material_names_match_byte_for_byte(tmp_path):
    """Names in Latin-1 (not UTF-8) stay apart, and a `#` in them is part of
    the name in both the OBJ and the MTL."""
    import scan_io

    source = _two_material_obj(tmp_path, "")
    mtl = "newmtl Wand_\xe4\nmap_Kd t0.png\nnewmtl Material #26\nmap_Kd t1.png\n"
    (tmp_path / "m.mtl").write_bytes(mtl.encode("latin-1"))
    obj = source.read_text().replace("usemtl a", "usemtl Wand_\xe4").replace("usemtl b", "usemtl Material #26")
    source.write_bytes(obj.encode("latin-1"))
    scan = scan_io.load(source)
    assert scan.face_page.tolist() == [0, 0, 1, 1] and not scan.warnings, scan.warnings
    assert [p.name for p in scan.page_images] == ["t0.png", "t1.png"]


def test_obj_materials_without_a_definition_are_named(tmp_path):
    """A material no library defines, and a library that is missing, each
    leave faces untextured with a warning, not in silence."""
    import scan_io

    source = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\n")
    scan = scan_io.load(source)
    assert scan.face_page.tolist() == [0, 0, -1, -1]
    assert scan.warnings == ["material 'b' is defined in no material library: its 2 faces are left untextured"]
    # A comment after the name is no library, and a second name that is missing is said.
    source.write_text(source.read_text().replace("mtllib m.mtl", "mtllib m.mtl gone.mtl # by Exporter 1.0"))
    commented = scan_io.load(source)
    assert commented.warnings == ["material library gone.mtl not found beside m.obj: the materials it defines "
                                  "are left untextured"], commented.warnings
    (tmp_path / "m.mtl").unlink()
    with_no_library = scan_io.load(source)
    assert with_no_library.face_page.tolist() == [-1, -1, -1, -1]
    assert len(with_no_library.warnings) == 1 and "m.mtl gone.mtl # by Exporter 1.0 not found" in \
        with_no_library.warnings[0], with_no_library.warnings


@pytest.mark.parametrize("options, refused", [
    ("-s 2 2 1", "-s 2 2 1"),
    ("-o 0.5", "-o 0.5"),
    ("-s 1e30 1e30 1 -o nan nan 0 -bm 1", "-s 1e30 1e30 1 -o nan nan 0"),
    ("-o 0 0 0 -s 1 1 0 -t 0 -bm 0.5 -clamp on", ""),  # the UVs as they are (w moves nothing)
])
def test_a_texture_read_through_moved_or_scaled_uvs_is_refused(tmp_path, options, refused):
    """Blender's importer reads such a map through a Mapping node; read
    without it, the scan would be baked from the wrong texels."""
    import scan_io

    path = _two_material_obj(tmp_path, f"newmtl a\nmap_Kd {options} t0.png\nnewmtl b\nmap_Kd t1.png\n")
    if not refused:
        assert scan_io.load(path).face_page.tolist() == [0, 0, 1, 1]
        return
    with pytest.raises(ValueError, match=f"material 'a' reads its texture through '{re.escape(refused)}'"):
        scan_io.load(path)


@pytest.mark.parametrize("vt, warned", [("0.1", False), ("1.3", True)])
def test_a_clamped_colour_map_is_warned_of_where_faces_leave_the_page(tmp_path, vt, warned):
    """-clamp on reads edge texels past [0, 1]; the bake repeats the image
    there. Material b repeats, so only a is named."""
    import scan_io

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd -clamp on t0.png\nnewmtl b\nmap_Kd -clamp off t1.png\n")
    path.write_text(path.read_text().replace("vt 0.1 0.1\n", f"vt {vt} 0.1\n"))
    warnings = scan_io.load(path).warnings
    assert warnings == (["material 'a' clamps its colour texture (-clamp on) where faces reach past its edges: "
                         "the new texture repeats it there"] if warned else []), warnings


def test_an_obj_texture_in_a_format_pillow_cannot_read_is_named(tmp_path):
    """An OpenEXR map (Blender's entries read it; this one reads what Pillow reads)."""
    import scan_io

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.exr\nnewmtl b\nmap_Kd t1.png\n")
    (tmp_path / "t0.exr").write_bytes(b"\x76\x2f\x31\x01" + bytes(60))
    with pytest.raises(ValueError, match="^its t0.exr is in no image format this reader decodes$"):
        scan_io.load(path)


def test_an_obj_may_name_two_material_libraries(tmp_path):
    import scan_io

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\n", "m.mtl")
    (tmp_path / "n.mtl").write_text("newmtl b\nmap_Kd t1.png\n")
    path.write_text(path.read_text().replace("mtllib m.mtl", "mtllib m.mtl n.mtl"))
    assert scan_io.load(path).face_page.tolist() == [0, 0, 1, 1]


def test_a_missing_texture_is_named_and_its_faces_left_untextured(tool_env, tmp_path):
    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd gone.png\n")
    proc = subprocess.run([sys.executable, str(CLI), str(path), str(tmp_path / "out")], env=tool_env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "warning: texture" in proc.stderr and "gone.png" in proc.stderr and "2 faces" in proc.stderr, proc.stderr
    # The output's MTL defines the material its untextured faces use.
    assert "newmtl untextured" in (tmp_path / "out" / "m_defrag.mtl").read_text()


def test_a_png_failing_only_an_ancillary_chunks_crc_is_read(tmp_path):
    """libpng drops such a chunk and reads the image; so does Blender."""
    import scan_io
    from atlas_defrag import png_files

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    png = png_files.encode_png(np.full((8, 8, 3), 90, np.uint8))
    text = b"tEXt" + b"Comment\x00scan"
    chunk = struct.pack(">I", len(text) - 4) + text + b"\x00\x00\x00\x00"  # a wrong CRC
    (tmp_path / "t1.png").write_bytes(png[:-12] + chunk + png[-12:])
    assert scan_io.load_image(tmp_path / "t1.png")[0, 0].tolist() == [90, 90, 90]


def _wrong_crc(png: bytes) -> bytes:
    """The PNG with its pixel data's CRC changed, the data whole."""
    kind = png.find(b"IDAT")
    at = kind + 4 + struct.unpack(">I", png[kind - 4:kind])[0]
    return png[:at] + bytes([png[at] ^ 1]) + png[at + 1:]


@pytest.mark.parametrize("damage", [lambda png: png[:len(png) * 2 // 3], _wrong_crc])
def test_a_texture_cut_short_or_failing_its_crc_ends_in_one_line(tool_env, tmp_path, damage):
    """Its header whole (so the layout runs), its pixels cut short; or its
    pixel data whole but its CRC wrong, which Blender refuses too."""
    from atlas_defrag import png_files

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    noise = np.random.default_rng(3).integers(0, 256, (64, 64, 3), dtype=np.uint8)
    png = png_files.encode_png(noise)
    (tmp_path / "t1.png").write_bytes(damage(png))
    proc = subprocess.run([sys.executable, str(CLI), str(path), str(tmp_path / "out")], env=tool_env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "cannot read the texture" in proc.stderr and "t1.png" in proc.stderr, proc.stderr


def test_a_texture_claiming_more_pixels_than_memory_ends_in_one_line(tool_env, tmp_path):
    """A PNG header claiming 300000 x 300000 pixels (a broken or hostile file)
    is refused before the layout scales charts to it or decoding fills memory."""
    import struct
    import zlib

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    header = struct.pack(">IIBBBBB", 300000, 300000, 8, 2, 0, 0, 0)
    (tmp_path / "t1.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
                                      chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b""))
    proc = subprocess.run([sys.executable, str(CLI), str(path), str(tmp_path / "out")], env=tool_env,
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "t1.png" in proc.stderr and "300000 x 300000" in proc.stderr, proc.stderr


@pytest.mark.parametrize("start, message", [(b"\xff\xfe", "UTF-16"), (b"\x1f\x8b", "gzip-compressed")])
def test_obj_files_in_other_encodings_are_named(native, tmp_path, start, message):
    path = tmp_path / "t.obj"
    path.write_bytes(start + "v 0 0 0\n".encode("utf-16-le"))
    with pytest.raises(ValueError, match=message):
        native.read_obj(str(path))


def test_out_dir_problems_end_before_the_work_and_inputs_are_never_replaced(tool_env, tmp_path):
    path = _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd m_defrag_page0_base_color.png\n",
                             textures=("t0.png", "m_defrag_page0_base_color.png"))
    (tmp_path / "a_file").write_text("")
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()}
    for out, message in ((tmp_path / "a_file", "is not a folder"), (tmp_path / "a_file" / "sub", "is not a folder"),
                         (tmp_path, "would replace the input file")):
        proc = subprocess.run([sys.executable, str(CLI), str(path), str(out)], env=tool_env,
                              capture_output=True, text=True, timeout=120)
        assert proc.returncode == 1 and "Traceback" not in proc.stderr and message in proc.stderr, proc.stderr
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir() if p.is_file()} == before


def test_an_input_named_as_the_output_obj_or_mtl_is_refused_before_the_work(tmp_path, monkeypatch, capsys):
    """The OBJ and MTL names are known before the layout: an input MTL of the
    output's name ends the run before the job, not after it."""
    import defrag_scan

    _two_material_obj(tmp_path, "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n", mtllib="m_defrag.mtl")

    def job_run(*args, **kwargs):
        raise AssertionError("the job ran")
    monkeypatch.setattr(defrag_scan.job, "run", job_run)
    assert defrag_scan.main([str(tmp_path / "m.obj"), str(tmp_path)]) == 1
    assert "would replace the input file" in capsys.readouterr().err


def test_gltf_colour_texture_reads_the_texcoord_set_it_names(tmp_path):
    import json

    import scan_io

    path = _textured_triangle_gltf(tmp_path, {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}}},
                                   {"source": 0})
    gltf = json.loads(path.read_text())
    gltf["meshes"][0]["primitives"][0]["attributes"] = {"POSITION": 0, "TEXCOORD_0": 0, "TEXCOORD_1": 1}
    path.write_text(json.dumps(gltf))
    scan = scan_io.load(path)
    assert scan.face_page.tolist() == [0]
    assert scan.uvs[0].tolist() == [[0, 1], [1, 1], [0, 0]]  # TEXCOORD_1, v turned up


@pytest.mark.parametrize("line_end, start", [("\n", ""), ("\r\n", ""), ("\r", ""), ("\n", "\ufeff")])
def test_obj_reader_takes_every_line_end_and_a_byte_order_mark(native, tmp_path, line_end, start):
    path = tmp_path / "t.obj"
    lines = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "vt 0 0", "f 1/1 2/1 3/1", "f 3/1 2/1 1/1"]
    path.write_bytes((start + line_end.join(lines) + line_end).encode("utf-8"))
    obj = native.read_obj(str(path))
    assert obj["positions"].shape == (3, 3) and obj["triangles"].tolist() == [[0, 1, 2], [2, 1, 0]]


def _glb_with_more_instances(source: Path, target: Path, transforms: list) -> None:
    """source (a GLB of one mesh node) with one more node per transform (glTF
    node fields: translation, scale) drawing the same mesh."""
    import json

    data = source.read_bytes()
    json_len = struct.unpack_from("<I", data, 12)[0]
    gltf, binary_chunk = json.loads(data[20:20 + json_len]), data[20 + json_len:]
    mesh = next(n["mesh"] for n in gltf["nodes"] if "mesh" in n)
    for fields in transforms:
        gltf["scenes"][gltf.get("scene", 0)]["nodes"].append(len(gltf["nodes"]))
        gltf["nodes"].append(dict(mesh=mesh, **fields))
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    target.write_bytes(struct.pack("<III", 0x46546C67, 2, 20 + len(text) + len(binary_chunk))
                       + struct.pack("<II", len(text), 0x4E4F534A) + text + binary_chunk)


def test_cli_lays_a_mesh_drawn_by_several_nodes_out_once(native, scans, scan_path, tool_env, tmp_path):
    """Two more nodes draw the Smithsonian mesh, one of them mirrored: every
    instance takes the first one's new UVs (as they share UVs in the file),
    and the page and the metrics are those of one instance."""
    import scan_io

    source = tmp_path / "three.glb"
    _glb_with_more_instances(scan_path("smithsonian"), source,
                             [{"translation": [0.5, 0, 0]}, {"scale": [-1, 1, 1], "translation": [0, 0.5, 0]}])
    run = subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path / "out"), "--metrics"],
                         capture_output=True, text=True, timeout=300, env=tool_env)
    assert run.returncode == 0, run.stderr
    one = len(scans("smithsonian").triangles)
    assert f"{3 * one} faces ({2 * one} of them in further instances" in run.stdout
    assert "2367 -> " in run.stdout
    assert re.search(r"texels shared by two triangles \d+ -> 0\n", run.stdout)
    texels = int(re.search(r"texels +[\d,]+ -> ([\d,]+)", run.stdout).group(1).replace(",", ""))
    assert texels < 4096 * 1024, "the instances were laid out side by side"

    # Each instance's corners repeat the first's UVs, in reverse order where one
    # of them mirrors: the same relation in the file read and in the file written.
    read, written = scan_io.load(source), scan_io.load(tmp_path / "out" / "three_defrag.obj")
    blocks = [slice(k * one, (k + 1) * one) for k in range(3)]
    reversed_blocks = 0
    for block in blocks[1:]:
        turned = not np.array_equal(read.uvs[block], read.uvs[blocks[0]])
        reversed_blocks += turned
        expected = read.uvs[blocks[0]][:, ::-1] if turned else read.uvs[blocks[0]]
        assert np.array_equal(read.uvs[block], expected)
        expected = written.uvs[blocks[0]][:, ::-1] if turned else written.uvs[blocks[0]]
        assert np.array_equal(written.uvs[block], expected)
    assert reversed_blocks > 0  # the mirrored instance is among them, or is the first
    first = blocks[0]
    m = native.measure(written.positions, written.triangles[first], read.uvs[first], read.face_page[first],
                       read.page_sizes, written.uvs[first], written.face_page[first], written.page_sizes)
    assert m["new"]["flipped_faces"] == 0 and m["new"]["overlap_texels"] == 0


@pytest.mark.parametrize("broken, failure, message", [
    ("png_files.write_pngs", "RuntimeError('the encoder broke')", "the encoder broke"),
    ("_native.write_obj", "OSError(28, 'No space left on device')", "writing into"),
])
def test_a_failed_write_leaves_the_earlier_runs_files_as_they_were(tmp_path, tool_env, broken, failure, message):
    """Whatever stops the writing (the PNG encoder, a full disk), no OBJ is
    left naming images that were not written, a run over an earlier one's
    output leaves those files whole (it writes beside them first), and the
    folders a run made for its output go again."""
    source = _two_material_obj(tmp_path / "in", "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    out = tmp_path / "out"
    assert subprocess.run([sys.executable, str(CLI), str(source), str(out)], capture_output=True,
                          timeout=300, env=tool_env).returncode == 0
    earlier = {p.name: p.read_bytes() for p in out.iterdir()}
    code = (f"import sys, defrag_scan\ndef broken(*args): raise {failure}\n"
            f"defrag_scan.{broken} = broken\nsys.exit(defrag_scan.main(sys.argv[1:]))\n")
    env = dict(tool_env, PYTHONPATH=os.pathsep.join([str(CLI.parent), tool_env["PYTHONPATH"]]))
    for folder in (out, tmp_path / "fresh" / "maps"):
        run = subprocess.run([sys.executable, "-c", code, str(source), str(folder)], capture_output=True, text=True,
                             timeout=300, env=env)
        assert run.returncode == 1 and message in run.stderr, run.stderr
        assert "Traceback" not in run.stderr or "OSError" not in failure, run.stderr  # a full disk: one line
    assert {p.name: p.read_bytes() for p in out.iterdir()} == earlier
    assert not (tmp_path / "fresh").exists()


def test_pages_an_earlier_run_wrote_beyond_this_ones_go(tmp_path, tool_env):
    """A run over an earlier one's output that wrote more pages or maps
    takes away the images its model no longer names, and only those."""
    source = _two_material_obj(tmp_path / "in", "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    out = tmp_path / "out"
    run = lambda: subprocess.run([sys.executable, str(CLI), str(source), str(out)], capture_output=True,
                                 timeout=300, env=tool_env)
    assert run().returncode == 0
    written = sorted(p.name for p in out.iterdir())
    stem = f"{source.stem}_defrag"
    stale = [f"{stem}_page7_base_color.png", f"{stem}_page0_normal.png"]
    others = ["notes_page1_base_color.png", f"{stem}_page0_base_color.png.bak", f"{stem}_page_x.png",
              f"{stem}_page0_base_color_retouched.png"]
    for name in stale + others:
        (out / name).write_bytes(b"earlier")
    (out / f"{stem}_page8_base_color.png").mkdir()  # a folder so named is no page
    (out / f"{stem}_page8_base_color.png" / "work.txt").write_text("mine")
    assert run().returncode == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(written + others + [f"{stem}_page8_base_color.png"])
    assert (out / f"{stem}_page8_base_color.png" / "work.txt").read_text() == "mine"


def _run_twice_the_image_move_hit(tmp_path, tool_env, hit: str):
    """(source, OUT_DIR, the second run): a two-material OBJ written into
    OUT_DIR, then again with `hit` (lines of Python, indented 8) run in place
    of the first move of the page-0 image into OUT_DIR, the MTL moved already."""
    source = _two_material_obj(tmp_path / "in", "newmtl a\nmap_Kd t0.png\nnewmtl b\nmap_Kd t1.png\n")
    out = tmp_path / "out"
    assert subprocess.run([sys.executable, str(CLI), str(source), str(out)], capture_output=True,
                          timeout=300, env=tool_env).returncode == 0
    code = ("import os, signal, sys, defrag_scan\nreal, failed = os.replace, []\n"
            "def replace(src, dst):\n"
            "    if str(dst).endswith('_page0_base_color.png') and '.replaced' not in str(dst) and not failed:\n"
            f"        failed.append(dst)\n{hit}\n"
            "    real(src, dst)\nos.replace = replace\nsys.exit(defrag_scan.main(sys.argv[1:]))\n")
    env = dict(tool_env, PYTHONPATH=os.pathsep.join([str(CLI.parent), tool_env["PYTHONPATH"]]))
    return source, out, lambda: subprocess.run([sys.executable, "-c", code, str(source), str(out)],
                                               capture_output=True, text=True, timeout=300, env=env)


def test_a_move_into_place_that_fails_puts_back_the_files_already_replaced(tmp_path, tool_env):
    """The image's move fails after the MTL was moved over an earlier run's:
    it is put back (the very file, not a copy), and nothing of the new run
    is left."""
    _, out, second = _run_twice_the_image_move_hit(
        tmp_path, tool_env, "        raise OSError(28, 'No space left on device')")
    earlier = {p.name: (p.stat().st_ino, p.read_bytes()) for p in out.iterdir()}
    assert "m_defrag.mtl" in earlier and "m_defrag_page0_base_color.png" in earlier, earlier.keys()
    run = second()
    assert run.returncode == 1 and "No space left" in run.stderr, run.stderr
    assert {p.name: (p.stat().st_ino, p.read_bytes()) for p in out.iterdir()} == earlier


def test_a_run_killed_while_moving_its_files_in_is_named_by_the_next(tmp_path, tool_env):
    """Killed (SIGKILL: no clean-up) after the MTL replaced an earlier run's:
    the earlier MTL waits in the scratch folder, and the next run says where."""
    source, out, second = _run_twice_the_image_move_hit(
        tmp_path, tool_env, "        os.kill(os.getpid(), signal.SIGKILL)")
    earlier_mtl = (out / "m_defrag.mtl").read_bytes()
    killed = second()
    assert killed.returncode == -9, killed.stderr
    kept = list(out.glob(".defrag_scan_*/.replaced/m_defrag.mtl"))
    assert len(kept) == 1 and kept[0].read_bytes() == earlier_mtl
    again = subprocess.run([sys.executable, str(CLI), str(source), str(out)], capture_output=True, text=True,
                           timeout=300, env=tool_env)
    assert again.returncode == 0, again.stderr
    assert f"{kept[0].parent} holds files of an earlier output" in again.stderr, again.stderr
    assert "m_defrag.mtl" in again.stderr and kept[0].read_bytes() == earlier_mtl


def test_the_native_obj_writer_fails_as_python_writes_do(native, tmp_path):
    """A file the writer cannot write is an OSError with its errno (a full disk here)."""
    args = (np.zeros((3, 3)), np.array([[0, 1, 2]]), np.zeros((1, 3, 2)), np.zeros(1, np.int64), ["a"])
    with pytest.raises(OSError) as caught:
        native.write_obj("/dev/full", "m.mtl", *args)
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == "/dev/full"
    with pytest.raises(FileNotFoundError):
        native.write_obj(str(tmp_path / "no" / "m.obj"), "m.mtl", *args)
    with pytest.raises(ValueError, match="null character"):  # the C library would write m.txt
        native.write_obj(str(tmp_path / "m.txt\0.obj"), "m.mtl", *args)
    with pytest.raises(ValueError, match="null character"):
        native.read_obj(str(tmp_path / "m.txt\0.obj"))
    assert list(tmp_path.iterdir()) == []


def test_obj_maps_beside_the_base_colour_are_carried_over(tmp_path, tool_env):
    """Blender writes a normal map as `map_Bump -bm 1.0 file`, and this entry
    writes `norm`, `map_ao` and `map_Ke`: the reader takes them (the command
    line reads its own output back whole), and leaves out with a warning a
    missing map and a grey bump map (heights, not normals)."""
    import scan_io
    from atlas_defrag import png_files

    mtl = ("newmtl a\nmap_Kd t0.png\nmap_Bump -bm 1.000000 n0.png\nmap_ao ao.png\nmap_Ke ao.png\n"
           "newmtl b\nmap_Kd t1.png\nbump -bm 0.5 height.png\nmap_ao missing.png\n")
    source = _two_material_obj(tmp_path / "in", mtl)
    (source.parent / "n0.png").write_bytes(png_files.encode_png(np.full((8, 8, 3), (128, 128, 255), np.uint8)))
    (source.parent / "ao.png").write_bytes(png_files.encode_png(np.full((8, 8, 1), 200, np.uint8)))
    (source.parent / "height.png").write_bytes(png_files.encode_png(np.full((8, 8, 1), 90, np.uint8)))
    scan = scan_io.load(source)
    assert [sorted(page) for page in scan.maps] == [["base_color", "emission", "normal", "occlusion"], ["base_color"]]
    assert scan.maps[0]["normal"].name == "n0.png" and scan.maps[0]["occlusion"].name == "ao.png"
    assert any("height.png" in w and "height map" in w for w in scan.warnings), scan.warnings
    assert any("missing.png" in w and "not found" in w for w in scan.warnings), scan.warnings
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, str(CLI), str(source), str(out)], capture_output=True, text=True,
                         timeout=300, env=tool_env)
    assert run.returncode == 0, run.stderr
    again = scan_io.load(out / "m_defrag.obj")
    assert sorted(again.maps[0]) == ["base_color", "emission", "normal", "occlusion"], again.maps
