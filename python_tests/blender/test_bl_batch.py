# SPDX-License-Identifier: MIT
"""The batch entry (addon/atlas_defrag/batch.py) in Blender 3.4 and in bpy 4.5."""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
import time
import urllib.parse
from pathlib import Path

import numpy as np
import pytest

import blhelp as H
from blenv import ADDON_PARENT, BLENDER, require_native, run_blender

BATCH = ADDON_PARENT / "atlas_defrag" / "batch.py"
BOX_GLB = H.ASSIMP / "glTF2" / "BoxTextured-glTF-Binary" / "BoxTextured.glb"
NO_UV_OBJ = H.ASSIMP / "OBJ" / "box.obj"  # no texture coordinates at all


def blender34_batch(*args, env=None):
    return run_blender(["--python", str(BATCH), "--"] + [str(a) for a in args], env=env)


def bpy45_batch(*args):
    env = dict(os.environ)
    return subprocess.run([sys.executable, str(BATCH)] + [str(a) for a in args], capture_output=True, text=True,
                          timeout=900, env=env)


@pytest.fixture(scope="module", autouse=True)
def _native_built():
    require_native()


def _read_obj_output(path):
    text = path.read_text()
    mtllib = [ln.split(None, 1)[1].strip() for ln in text.splitlines() if ln.startswith("mtllib")]
    assert mtllib, "no mtllib"
    mtl = (path.parent / mtllib[0]).read_text()
    maps = [ln.split(None, 1)[1].strip() for ln in mtl.splitlines() if ln.strip().startswith("map_Kd")]
    return text, maps


def test_batch34_obj_to_obj(tmp_path):
    out = tmp_path / "out" / "tetra.obj"
    rep = tmp_path / "out" / "tetra.json"
    proc = blender34_batch(H.model_path("tetra"), out, "--report", rep, "--padding", "2")
    assert proc.returncode == 0, proc.stderr[-3000:]
    text, maps = _read_obj_output(out)
    assert maps and all(m.endswith(".png") and "_defrag" in m for m in maps), maps
    for m in maps:
        assert (out.parent / m).is_file(), m
    report = json.loads(rep.read_text())
    assert report["status"] == "ok"
    obj = report["objects"][0]
    assert obj["charts_after"] < obj["charts_before"]
    assert obj["new_map_first"], "the source map, the mesh's only one, is gone: the new one is first"
    # Only the model's files, no scratch folder left behind.
    assert sorted(p.name for p in out.parent.iterdir() if p.name.startswith(".")) == []
    # The output loads back: one UV map, the new texture on the material.
    vt = sum(1 for ln in text.splitlines() if ln.startswith("vt "))
    assert vt > 0
    # --skip-existing does nothing the second time.
    t = time.perf_counter()
    proc = blender34_batch(H.model_path("tetra"), out, "--skip-existing")
    assert proc.returncode == 0 and "skipped" in proc.stdout, proc.stdout + proc.stderr
    assert time.perf_counter() - t < 60


def test_batch34_a_rerun_with_fewer_pages_takes_away_the_earlier_ones(tmp_path):
    """The same OBJ output written again with fewer pages: the images only
    the earlier output named go with it, and a file it did not name stays."""
    out = tmp_path / "out" / "tetra.obj"
    assert blender34_batch(H.model_path("tetra"), out, "--max-page-size", "512").returncode == 0
    assert len(_read_obj_output(out)[1]) > 1
    (out.parent / "notes.png").write_bytes(b"mine")
    proc = blender34_batch(H.model_path("tetra"), out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    maps = _read_obj_output(out)[1]
    assert len(maps) == 1
    assert sorted(p.name for p in out.parent.iterdir()) == sorted(["tetra.obj", "tetra.mtl", "notes.png"] + maps)


def test_batch34_a_run_over_an_obj_it_did_not_write_takes_away_nothing(tmp_path):
    """An OBJ output written over one this entry did not write (a library of
    another name, shared with another model, naming images named like this
    entry's): every file of the other models stays."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "common.mtl").write_text("newmtl m\nmap_Kd old_texture.png\n")
    for name in ("old.obj", "other.obj"):
        (out / name).write_text("mtllib common.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    (out / "old_texture.png").write_bytes(b"theirs")
    proc = blender34_batch(H.model_path("tetra"), out / "old.obj")
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert (out / "common.mtl").is_file() and (out / "old_texture.png").read_bytes() == b"theirs"


def test_batch34_glb_to_glb(tmp_path):
    out = tmp_path / "box.glb"
    cache = tmp_path / "cache"
    proc = blender34_batch(BOX_GLB, out, "--report", tmp_path / "r.json", env={"XDG_CACHE_HOME": str(cache)})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert out.is_file() and out.read_bytes()[:4] == b"glTF"
    _check_glb(out)
    # Blender writes no bytecode; the batch entry caches the glTF add-on's and
    # its own in the user's cache, so the next model's process need not compile them.
    prefix = cache / "atlas_defrag" / "pycache"
    pycs = list(prefix.rglob("*.pyc"))
    named = {p.name.split(".")[0] for p in pycs}
    assert {"gltf2_blender_export", "gltf2_blender_gltf", "write_bpy", "api"} <= named, sorted(named)
    # So are Blender's start-up scripts, imported before the entry ran; a
    # Blender started with PYTHONPYCACHEPREFIX naming the cache reads them
    # (Python's verbose flag names each code object read from a file).
    startup = [p for p in pycs if p.parent.name == "bl_ui" and p.name.startswith("__init__.")]
    assert startup, sorted(named)
    proc = blender34_batch(BOX_GLB, tmp_path / "again.glb",
                           env={"XDG_CACHE_HOME": str(cache), "PYTHONPYCACHEPREFIX": str(prefix), "PYTHONVERBOSE": "1"})
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert f"code object from '{startup[0]}'" in proc.stderr, proc.stderr[-3000:]


def _check_glb(path):
    import struct
    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    gltf = json.loads(data[20:20 + n])
    prim = gltf["meshes"][0]["primitives"][0]
    assert "TEXCOORD_0" in prim["attributes"] and "TEXCOORD_1" not in prim["attributes"], prim["attributes"]
    assert gltf.get("images"), "no image"
    names = [im.get("name", "") for im in gltf["images"]]
    assert any("_defrag" in nm for nm in names), names
    return gltf


def test_batch45_obj_to_glb_and_back(tmp_path):
    """bpy 4.5 as a module runs the same entry (python batch.py IN OUT)."""
    out = tmp_path / "tetra.glb"
    proc = bpy45_batch(H.model_path("tetra"), out, "--report", tmp_path / "r.json")
    assert proc.returncode == 0, proc.stderr[-3000:]
    gltf = _check_glb(out)
    assert json.loads((tmp_path / "r.json").read_text())["status"] == "ok"
    assert gltf["meshes"]


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_glb_of_a_scan_without_normals_writes_none(tmp_path, runner):
    """Meshroom's OBJ has no normals, so Blender shades it flat: the GLB then
    carries no NORMAL (glTF clients compute flat normals), whereas tetra's
    OBJ has normals and keeps them."""
    batch = blender34_batch if runner == "blender34" else bpy45_batch
    for model, has_normals in (("meshroom", False), ("tetra", True)):
        out = tmp_path / f"{model}.glb"
        proc = batch(H.model_path(model), out)
        assert proc.returncode == 0, proc.stderr[-3000:]
        attributes = _check_glb(out)["meshes"][0]["primitives"][0]["attributes"]
        assert ("NORMAL" in attributes) == has_normals, (model, attributes)


def test_batch45_glb_to_obj(tmp_path):
    out = tmp_path / "box.obj"
    proc = bpy45_batch(BOX_GLB, out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    _, maps = _read_obj_output(out)
    assert maps and all((tmp_path / m).is_file() for m in maps), maps


def test_batch45_glb_with_a_map_obj_cannot_name_to_obj(tmp_path):
    """The Smithsonian scan's occlusion map goes beside the OBJ, whose MTL
    cannot name it: a warning, not a failure, and a note in the MTL, by
    which a rerun replaces the file rather than writing a numbered copy. A
    name with a space is read whole."""
    out = tmp_path / "my scan.obj"
    for _ in range(2):
        proc = bpy45_batch(H.model_path("smithsonian"), out)
        assert proc.returncode == 0, proc.stderr[-3000:]
        assert "its materials do not name them" in proc.stderr, proc.stderr[-2000:]
        files = sorted(p.name for p in tmp_path.iterdir())
        _, maps = _read_obj_output(out)
        assert maps and all(m.startswith("my scan_") and (tmp_path / m).is_file() for m in maps), maps
    assert not any(".001" in name for name in files), files


def test_batch45_gltf_holds_its_data(tmp_path):
    """Blender 4.2 and later write glTF with embedded data only when allowed."""
    out = tmp_path / "tetra.gltf"
    proc = bpy45_batch(H.model_path("tetra"), out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    gltf = json.loads(out.read_text())
    assert gltf.get("images") and all(b["uri"].startswith("data:") for b in gltf["buffers"]), gltf.get("buffers")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tetra.gltf"]


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_failures(tmp_path, runner):
    run = blender34_batch if runner == "blender34" else bpy45_batch
    proc = run(tmp_path / "missing.obj", tmp_path / "o.obj", "--report", tmp_path / "r.json")
    assert proc.returncode == 1 and "input not found" in proc.stderr, proc.stderr[-2000:]
    assert json.loads((tmp_path / "r.json").read_text())["status"] == "error"
    proc = run(NO_UV_OBJ, tmp_path / "o2.obj")
    assert proc.returncode == 1 and "has no uv map" in proc.stderr.lower(), proc.stderr[-2000:]
    assert not (tmp_path / "o2.obj").exists()
    proc = run(H.model_path("tetra"), tmp_path / "o3.fbx")  # a usage error, before Blender works
    assert proc.returncode == 2 and "unsupported output" in proc.stderr, proc.stderr[-2000:]
    proc = run(H.ASSIMP / "OBJ" / "point_cloud.obj", tmp_path / "o4.glb")  # vertices only
    assert proc.returncode == 1 and "has no faces" in proc.stderr, proc.stderr[-2000:]


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_glb_whose_exporter_drops_the_new_texture_fails(tmp_path, runner):
    """A specular-glossiness material imports as shader nodes that Blender's
    glTF exporter cannot write back: the GLB would hold no image. That is a
    failure, not a model without its atlas reported as done."""
    run = blender34_batch if runner == "blender34" else bpy45_batch
    source = H.ASSIMP / "glTF2" / "BoxTextured-glTF-pbrSpecularGlossiness" / "BoxTextured.gltf"
    out = tmp_path / "out" / "box.glb"
    proc = run(source, out)
    if proc.returncode == 0:  # this exporter writes the material after all
        assert _check_glb(out).get("images"), proc.stderr[-2000:]
        return
    assert proc.returncode == 1 and "wrote none of the new images" in proc.stderr, proc.stderr[-2000:]
    assert list(out.parent.iterdir()) == []


@pytest.mark.parametrize("packed", [False, True])
def test_batch34_obj_carries_the_maps_of_materials_it_left_unchanged(tmp_path, packed):
    """Materials read through a texture transform are left as they are: their
    images are copied beside the OBJ, named after it, so that every map the
    MTL names is there. Packed in a GLB, such an image has no file, and
    Blender's exporter would name none."""
    source = H.ASSIMP / "glTF2" / "textureTransform" / "TextureTransformTest.gltf"
    if packed:
        source = _as_glb(source, tmp_path / "tt.glb")
    out = tmp_path / "out" / "tt.obj"
    proc = blender34_batch(source, out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    text, maps = _read_obj_output(out)
    names = {m.split()[-1] for m in maps}
    mtl = (out.parent / "tt.mtl").read_text()
    assert len(maps) == mtl.count("newmtl"), mtl  # every material keeps its map
    assert {"tt_Arrow.png", "tt_UV.png"} <= names or packed, names
    assert all((out.parent / n).is_file() for n in names), sorted(p.name for p in out.parent.iterdir())


def test_batch34_obj_maps_left_unchanged_never_share_a_file_with_another_models(tmp_path):
    """Two models whose unchanged materials read images of one name with
    other pixels, written into one folder: each MTL names its own model's."""
    from atlas_defrag import png_files

    out = tmp_path / "out"
    for k, model in enumerate(("one", "two")):
        folder = tmp_path / model
        folder.mkdir()
        (folder / "tex.png").write_bytes(png_files.encode_png(np.full((8, 8, 3), 60 + 100 * k, np.uint8)))
        (folder / "m.mtl").write_text("newmtl a\nmap_Kd tex.png\nnewmtl b\nmap_Kd -s 2 2 1 tex.png\n")
        (folder / "m.obj").write_text(
            "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
            "vt 0.1 0.1\nvt 0.9 0.1\nvt 0.9 0.9\nvt 0.1 0.9\n"
            "usemtl a\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\nusemtl b\nf 2/1 5/2 6/3\nf 2/1 6/3 3/4\n")
        proc = blender34_batch(folder / "m.obj", out / f"{model}.obj")
        assert proc.returncode == 0, proc.stderr[-3000:]
    for model in ("one", "two"):
        _, maps = _read_obj_output(out / f"{model}.obj")
        scaled = [m.split()[-1] for m in maps if m.startswith("-s")]
        assert len(scaled) == 1, maps
        assert (out / scaled[0]).read_bytes() == (tmp_path / model / "tex.png").read_bytes(), model


def test_batch34_refuses_an_output_that_is_a_folder(tmp_path):
    """A folder at OUT (or at the MTL's name) is refused, its files kept: a
    run sets an earlier output aside in its scratch folder and removes it."""
    for name in ("tetra.obj", "tetra.mtl"):
        folder = tmp_path / name.split(".")[1] / name
        folder.mkdir(parents=True)
        (folder / "keep.txt").write_text("mine")
        proc = blender34_batch(H.model_path("tetra"), folder.parent / "tetra.obj")
        assert proc.returncode == 1 and "is a folder" in proc.stderr, proc.stderr[-2000:]
        assert (folder / "keep.txt").read_text() == "mine"
        assert sorted(p.name for p in folder.parent.iterdir()) == [name]


def _as_glb(source: Path, target: Path) -> Path:
    """source, a .gltf whose buffers and images are files beside it, as one
    GLB that holds them all (its images packed, with no file name)."""
    gltf = json.loads(source.read_text())
    blob = bytearray()

    def append(data: bytes) -> int:
        blob.extend(b"\0" * (-len(blob) % 4))
        blob.extend(data)
        return len(blob) - len(data)

    starts = [append((source.parent / b["uri"]).read_bytes()) for b in gltf["buffers"]]
    for view in gltf.get("bufferViews", []):
        view["byteOffset"] = view.get("byteOffset", 0) + starts[view["buffer"]]
        view["buffer"] = 0
    for image in gltf.get("images", []):
        data = (source.parent / urllib.parse.unquote(image.pop("uri"))).read_bytes()
        gltf["bufferViews"].append({"buffer": 0, "byteOffset": append(data), "byteLength": len(data)})
        image.update(bufferView=len(gltf["bufferViews"]) - 1,
                     mimeType="image/png" if data.startswith(b"\x89PNG") else "image/jpeg")
    blob.extend(b"\0" * (-len(blob) % 4))
    gltf["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    target.write_bytes(b"glTF" + struct.pack("<II", 2, 28 + len(text) + len(blob)) + struct.pack("<I", len(text))
                       + b"JSON" + text + struct.pack("<I", len(blob)) + b"BIN\0" + bytes(blob))
    return target


def test_batch_many_in_parallel(tmp_path):
    """Folder/list form: one Blender per model, two at once, skipping done
    ones, each model's warnings passed on (tetra's MTL names an image '*1'
    that is not there)."""
    out = tmp_path / "out"
    env = dict(os.environ, BLENDER=BLENDER)
    cmd = [sys.executable, str(BATCH), "--out-dir", str(out), "--jobs", "2", "--format", "glb",
           H.model_path("tetra"), str(BOX_GLB)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "  atlas_defrag: warning: Image '*1'" in proc.stderr, proc.stderr
    assert (out / "teTra-Mk5-miniature-model.glb").is_file() and (out / "BoxTextured.glb").is_file()
    assert (out / "BoxTextured.report.json").is_file()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0 and "0 done, 2 skipped" in proc.stdout, proc.stdout + proc.stderr


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_ply_with_texture_comment(tmp_path, runner):
    """PLY carries no material: the image named by 'comment TextureFile' is used."""
    src = (H.ASSIMP / "PLY" / "cube_uv.ply").read_text().splitlines()
    src.insert(2, "comment TextureFile tex.jpg")
    ply = tmp_path / "cube.ply"
    ply.write_text("\n".join(src) + "\n")
    (tmp_path / "tex.jpg").write_bytes((H.ASSIMP / "OBJ" / "SpiderTex.jpg").read_bytes())
    run = blender34_batch if runner == "blender34" else bpy45_batch
    out = tmp_path / "out" / "cube.obj"
    proc = run(ply, out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    _, maps = _read_obj_output(out)
    assert maps == ["cube_tex_defrag.png"], maps  # named after the output model
    assert (out.parent / "cube_tex_defrag.png").is_file()


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_ply_keeps_its_vertex_colours(tmp_path, runner):
    """A PLY's vertex colours stay on the mesh and reach the GLB (as linear
    values, glTF's colour space): 24 vertices of distinct colours."""
    import numpy as np

    import scan_io

    src = (H.ASSIMP / "PLY" / "cube_uv.ply").read_text().splitlines()
    body = src.index("end_header") + 1
    colours = np.array([[10 * i, 255 - 10 * i, 128] for i in range(24)])
    lines = src[:body] + [f"{row} {r} {g} {b}" for row, (r, g, b) in zip(src[body:body + 24], colours)]
    lines += src[body + 24:]
    at = lines.index("property float t") + 1
    lines[at:at] = ["property uchar red", "property uchar green", "property uchar blue"]
    lines.insert(2, "comment TextureFile tex.jpg")
    (tmp_path / "cube.ply").write_text("\n".join(lines) + "\n")
    (tmp_path / "tex.jpg").write_bytes((H.ASSIMP / "OBJ" / "SpiderTex.jpg").read_bytes())
    out = tmp_path / "out" / "cube.glb"
    proc = (blender34_batch if runner == "blender34" else bpy45_batch)(tmp_path / "cube.ply", out)
    assert proc.returncode == 0, proc.stderr[-3000:]
    data = out.read_bytes()
    n = int.from_bytes(data[12:16], "little")
    gltf, buffers = json.loads(data[20:20 + n]), [data[20 + n + 8:]]
    linear = np.where(colours / 255 <= 0.04045, colours / 255 / 12.92, ((colours / 255 + 0.055) / 1.055) ** 2.4)
    found = []
    for name, accessor in gltf["meshes"][0]["primitives"][0]["attributes"].items():
        rgb = scan_io._accessor(gltf, buffers, accessor)[:, :3] if name.startswith("COLOR_") else None
        if rgb is not None and np.abs(rgb[:, None, :] - linear[None]).max(axis=2).min(axis=1).max() < 2 / 255:
            found.append(len(np.unique(np.round(rgb, 3), axis=0)))
    assert found and found[0] == 24, gltf["meshes"][0]["primitives"][0]["attributes"]


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_batch_openmvs_ply_keeps_its_face_uvs(tmp_path, runner):
    """Per-face UVs reach the job: the tetra scan's charts merge as from its OBJ."""
    textured = H.openmvs_style_ply(tmp_path / "scan.ply")
    run = blender34_batch if runner == "blender34" else bpy45_batch
    out = tmp_path / "out" / "scan.obj"
    proc = run(tmp_path / "scan.ply", out, "--report", tmp_path / "r.json")
    assert proc.returncode == 0, proc.stderr[-3000:]
    (report,) = json.loads((tmp_path / "r.json").read_text())["objects"]
    assert textured > 13000 and report["charts_before"] == 159 and report["charts_after"] <= 40, report
    assert "untextured" not in proc.stderr, proc.stderr  # OpenMVS's texnumber -1 says so on purpose
    _, maps = _read_obj_output(out)
    assert maps == ["scan_textured_0_v2_defrag.png"], maps


def test_gnu_parallel_recipe_skips_what_is_done(tmp_path):
    """The README's GNU parallel recipe, with -S : (this machine as the one
    login) over three models: every output written; run again, nothing is
    redone (each job says it skipped, and no output changes)."""
    parallel = shutil.which("parallel")
    if parallel is None:
        pytest.fail("GNU parallel is missing: run scripts/setup.sh (Debian package 'parallel')")
    models = [H.model_path("tetra"), H.model_path("meshroom"), str(BOX_GLB)]
    out = tmp_path / "out"
    out.mkdir()
    cmd = [parallel, "--will-cite", "-S", ":", "-j2", BLENDER, "--background", "--factory-startup",
           "--python-exit-code", "1", "--python", str(BATCH), "--", "{}", str(out) + "/{/.}.glb",
           "--skip-existing", ":::"] + models

    first = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert first.returncode == 0, first.stdout[-3000:] + first.stderr[-3000:]
    outputs = sorted(out.glob("*.glb"))
    assert [p.stem for p in outputs] == sorted(os.path.splitext(os.path.basename(m))[0] for m in models)
    stamps = {p: p.stat().st_mtime_ns for p in outputs}
    assert first.stdout.count("atlas_defrag: wrote") == 3, first.stdout[-3000:]

    second = subprocess.run(cmd, capture_output=True, text=True, timeout=900)
    assert second.returncode == 0, second.stdout[-3000:] + second.stderr[-3000:]
    assert second.stdout.count("atlas_defrag: skipped") == 3, second.stdout[-3000:]
    assert "atlas_defrag: wrote" not in second.stdout
    assert {p: p.stat().st_mtime_ns for p in out.glob("*.glb")} == stamps
