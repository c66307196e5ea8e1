# SPDX-License-Identifier: MIT
"""The batch entry under faults (issue 15): a full disk, outputs that would
overwrite inputs, name collisions between models, an unwritable report,
Ctrl-C, and a python3 without numpy on PATH."""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import blhelp as H
from blenv import ADDON_PARENT, BLENDER, require_native, run_blender

BATCH = ADDON_PARENT / "atlas_defrag" / "batch.py"

# Runs the batch entry with one writer broken the way a full disk breaks it.
# Blender's OBJ exporter reports success and leaves the file cut short and the
# MTL empty; the PNG writer raises ENOSPC after writing part of the file.
FAULTY = '''
import errno, os, sys
sys.path.insert(0, {parent!r})
from atlas_defrag import batch, png_files
fault = os.environ["ATLAS_FAULT"]
if fault == "obj":
    export = batch.export_model
    def cut_short(path, objects, **images):
        export(path, objects, **images)
        size = os.path.getsize(path)
        with open(path, "r+b") as f:
            f.truncate(size // 10)
        open(os.path.splitext(path)[0] + ".mtl", "w").close()
    batch.export_model = cut_short
elif fault == "png":
    def half_then_full(files):
        for path, pixels in files:
            with open(path, "wb") as f:
                f.write(png_files.encode_png(pixels)[:100])
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), path)
    png_files.write_pngs = half_then_full
argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
code = batch.main(argv)
sys.stdout.flush()
sys.exit(code)
'''


@pytest.fixture(scope="module", autouse=True)
def _native_built():
    require_native()


def _faulty_script(tmp_path):
    path = tmp_path / "faulty_batch.py"
    path.write_text(FAULTY.format(parent=str(ADDON_PARENT)))
    return path


def _left_in(folder: Path):
    return sorted(p.name for p in folder.iterdir()) if folder.exists() else []


@pytest.mark.parametrize("runner, fault", [("blender34", "obj"), ("bpy45", "png")])
def test_a_full_disk_leaves_nothing_and_fails(tmp_path, runner, fault):
    out_dir = tmp_path / "out"
    out_dir.mkdir()
    script = _faulty_script(tmp_path)
    args = [H.model_path("tetra"), out_dir / "tetra.obj", "--report", tmp_path / "r.json"]
    env = dict(os.environ, ATLAS_FAULT=fault)
    if runner == "blender34":
        proc = run_blender(["--python", str(script), "--"] + [str(a) for a in args], env={"ATLAS_FAULT": fault})
    else:
        proc = subprocess.run([sys.executable, str(script)] + [str(a) for a in args], capture_output=True,
                              text=True, timeout=900, env=env)
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "wrote" not in proc.stdout
    expected = "is the disk full" if fault == "obj" else "No space left on device"
    assert expected in proc.stderr, proc.stderr[-2000:]
    assert _left_in(out_dir) == []  # no model, no half PNG, no .atlas_defrag_* folder
    assert '"status": "error"' in (tmp_path / "r.json").read_text()


# The tetra scan's output: a 1.3 MB PNG, then a 1.2 MB OBJ. On 1 MB the PNG
# writer fails; on 1.5 MB the PNG fits and Blender's OBJ exporter runs out of
# room, yet reports success.
@pytest.mark.parametrize("size", ["1m", "1536k"])
def test_a_small_tmpfs_fills_up_and_leaves_nothing(tmp_path, size):
    """The real thing, where a tmpfs can be mounted (root, not in every CI)."""
    mount = tmp_path / "small"
    mount.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root")
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mount)], capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot mount a tmpfs here: " + done.stderr.decode(errors="replace").strip())
    try:
        proc = subprocess.run([sys.executable, str(BATCH), H.model_path("tetra"), str(mount / "tetra.obj")],
                              capture_output=True, text=True, timeout=900)
        assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
        assert _left_in(mount) == []
    finally:
        subprocess.run(["umount", str(mount)], check=False)


def _copy_tetra(folder: Path) -> Path:
    src = Path(H.model_path("tetra")).parent
    shutil.copytree(src, folder)
    for p in folder.rglob("*"):
        os.chmod(p, 0o755 if p.is_dir() else 0o644)
    return folder / "teTra-Mk5-miniature-model.obj"


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_outputs_that_would_overwrite_inputs_are_refused(tmp_path):
    model = _copy_tetra(tmp_path / "tetra")
    before = _digest(model.parent)
    # The model itself (named first, before its MTL); an output whose MTL is
    # the input's (mtllib 3Ddata.mtl).
    for out, clash in ((model, model), (model.parent / "3Ddata.obj", model.parent / "3Ddata.mtl")):
        proc = subprocess.run([sys.executable, str(BATCH), str(model), str(out)], capture_output=True, text=True,
                              timeout=900)
        assert proc.returncode == 1 and f"would overwrite the input file {clash}:" in proc.stderr, proc.stderr[-2000:]
    assert _digest(model.parent) == before


def _maps(obj_path: Path):
    text = obj_path.read_text()
    lib = next(ln.split(None, 1)[1].strip() for ln in text.splitlines() if ln.startswith("mtllib"))
    mtl = (obj_path.parent / lib).read_text()
    return [ln.split()[-1] for ln in mtl.splitlines() if ln.strip().startswith("map_Kd")]


def test_many_models_of_one_name_get_their_own_files(tmp_path):
    """a/X.obj, b/X.obj and c/X_2.obj into one folder as OBJ: three models,
    three sets of images (all three textures have the same name)."""
    names = [("a", "X"), ("b", "X"), ("c", "X_2")]
    inputs = []
    for folder, stem in names:
        model = _copy_tetra(tmp_path / folder)
        target = model.with_name(stem + ".obj")
        model.rename(target)
        inputs.append(str(target))
    out = tmp_path / "out"
    env = dict(os.environ, BLENDER=BLENDER)
    cmd = [sys.executable, str(BATCH), "--out-dir", str(out), "--format", "obj", "--jobs", "2"] + inputs
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=1800, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "3 done, 0 skipped" in proc.stdout, proc.stdout
    models = sorted(p.name for p in out.glob("*.obj"))
    assert models == ["X.obj", "X_2.obj", "X_2_2.obj"], models
    maps = {m: _maps(out / m) for m in models}
    flat = [name for ms in maps.values() for name in ms]
    assert len(flat) == len(set(flat)), maps  # no image shared between models
    for m, ms in maps.items():
        assert ms and all((out / n).is_file() and n.startswith(m[:-4] + "_") for n in ms), (m, ms)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert proc.returncode == 0 and "0 done, 3 skipped" in proc.stdout, proc.stdout + proc.stderr


def _square_model(folder: Path, stem: str, texture: str, colour) -> Path:
    """Two triangles textured in one colour through an MTL of the model's own."""
    from atlas_defrag import png_files

    folder.mkdir(exist_ok=True)
    (folder / texture).write_bytes(png_files.encode_png(np.full((16, 16, 3), colour, np.uint8)))
    (folder / f"{stem}.mtl").write_text(f"newmtl m\nmap_Kd {texture}\n")
    (folder / f"{stem}.obj").write_text(
        f"mtllib {stem}.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0.1 0.1\nvt 0.9 0.1\nvt 0.9 0.9\n"
        "vt 0.1 0.9\nusemtl m\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    return folder / f"{stem}.obj"


def test_models_whose_image_names_join_alike_keep_their_own(tmp_path):
    """Model a with texture x_tex.png and model a_x with tex.png would both
    name their new image a_x_tex_defrag.png in one output folder."""
    _square_model(tmp_path / "in", "a", "x_tex.png", (200, 0, 0))
    _square_model(tmp_path / "in", "a_x", "tex.png", (0, 0, 200))
    out = tmp_path / "out"
    cmd = [sys.executable, str(BATCH), "--out-dir", str(out), "--format", "obj", "--jobs", "1", str(tmp_path / "in")]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=dict(os.environ, BLENDER=BLENDER))
    assert proc.returncode == 0 and "2 done" in proc.stdout, proc.stdout + proc.stderr
    maps = {m: _maps(out / m) for m in ("a.obj", "a_x.obj")}
    assert len(maps["a.obj"]) == 1 and maps["a.obj"] != maps["a_x.obj"], maps
    from atlas_defrag import png_files
    for model, blue in (("a.obj", False), ("a_x.obj", True)):
        pixels = png_files.decode_png((out / maps[model][0]).read_bytes())
        assert (pixels[..., 2].max() > 100) == blue, (model, maps[model])


def test_faces_the_obj_import_drops_are_named_in_a_warning(tmp_path):
    """Blender's OBJ importer skips a face naming a vertex the file lacks:
    the run goes on, and says how many faces the output lacks."""
    model = _square_model(tmp_path, "square", "tex.png", (200, 0, 0))
    model.write_text(model.read_text() + "f 1/1 2/2 9/3\n")
    report = tmp_path / "report.json"
    out = tmp_path / "out" / "square.glb"
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(out), "--report", str(report)], timeout=300)
    assert proc.returncode == 0 and out.exists(), proc.stdout[-2000:] + proc.stderr[-2000:]
    expected = "OBJ importer made 2 of the 3 faces of square.obj"
    assert expected in proc.stderr, proc.stderr[-2000:]
    assert any(expected in w for w in json.loads(report.read_text())["warnings"])


def test_positions_blender_rounds_are_named_in_a_warning(tmp_path):
    """A 4 cm square at UTM northings: Blender's float32 steps by 0.25-0.5 m there."""
    model = _square_model(tmp_path, "square", "tex.png", (200, 0, 0))
    far = model.read_text().replace("v 0 0 0", "v 500000 4000000 0").replace("v 1 0 0", "v 500000.04 4000000 0")
    model.write_text(far.replace("v 1 1 0", "v 500000.04 4000000.04 0").replace("v 0 1 0", "v 500000 4000000.04 0"))
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(tmp_path / "out.glb")], timeout=300)
    assert "Blender's single precision steps by" in proc.stderr, proc.stdout[-2000:] + proc.stderr[-2000:]


def _claiming(fmt: str, width: int, height: int, junk: bytes = b"") -> bytes:
    """A 16 x 16 JPEG or DDS whose header claims width x height pixels; junk
    goes before a JPEG's frame header (libjpeg skips it, with a warning)."""
    from PIL import Image

    out = io.BytesIO()
    Image.new("RGB", (16, 16), (120, 80, 40)).save(out, fmt)
    data = bytearray(out.getvalue())
    if fmt == "DDS":
        struct.pack_into("<II", data, 12, height, width)
        return bytes(data)
    frame = data.find(b"\xff\xc0")
    struct.pack_into(">HH", data, frame + 5, height, width)
    return bytes(data[:frame] + junk + data[frame:])


def _square_glb(path: Path, jpeg: bytes) -> Path:
    """The square of _square_model as a GLB, its texture packed inside."""
    blobs = [np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32).tobytes(),
             np.array([[0.1, 0.1], [0.9, 0.1], [0.9, 0.9], [0.1, 0.9]], np.float32).tobytes(),
             np.array([0, 1, 2, 0, 2, 3], np.uint32).tobytes(), jpeg]
    views, body = [], b""
    for blob in blobs:
        views.append({"buffer": 0, "byteOffset": len(body), "byteLength": len(blob)})
        body += blob + bytes(-len(blob) % 4)
    accessors = [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                  "min": [0, 0, 0], "max": [1, 1, 0]},
                 {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"},
                 {"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}]
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2,
                                        "material": 0}]}],
            "materials": [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
            "textures": [{"source": 0}], "images": [{"bufferView": 3, "mimeType": "image/jpeg"}],
            "buffers": [{"byteLength": len(body)}], "bufferViews": views, "accessors": accessors}
    text = json.dumps(gltf).encode()
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(body), b"BIN\0") + body
    path.write_bytes(b"glTF" + struct.pack("<II", 2, 12 + len(chunks)) + chunks)
    return path


@pytest.mark.parametrize("fmt, junk, packed", [("JPEG", b"", False), ("JPEG", b"\x00", True), ("DDS", b"", False)])
def test_a_texture_claiming_more_pixels_than_blender_can_hand_out_is_refused(tmp_path, fmt, junk, packed):
    """A few hundred bytes claiming 60000 x 60000 pixels: asking Blender 3.4
    for a JPEG's size crashed it (bpy 4.5 decodes 14 GB and wraps the pixel
    count), and its OBJ importer decodes a DDS at once, until memory runs
    out. The headers are read first, a junk byte before a JPEG's frame
    header skipped as libjpeg skips it, and the model refused."""
    bomb = _claiming(fmt, 60000, 60000, junk)
    if packed:
        model = _square_glb(tmp_path / "square.glb", bomb)
    else:
        texture = "tex.jpg" if fmt == "JPEG" else "tex.dds"
        model = _square_model(tmp_path, "square", texture, (200, 0, 0))
        (tmp_path / texture).write_bytes(bomb)
    out = tmp_path / "out" / "square.glb"
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(out)], timeout=300)
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "claims 60000 x 60000 pixels: more than Blender can hand to Python" in proc.stderr, proc.stderr[-2000:]
    assert _left_in(out.parent) == []


def test_a_jpeg_cut_short_is_skipped_not_baked_grey(tmp_path):
    """libjpeg decodes half a JPEG, the rest grey: the texture is skipped as
    damaged (the model's only one here, so nothing is left to do)."""
    from PIL import Image

    model = _square_model(tmp_path, "square", "tex.jpg", (200, 0, 0))
    whole = io.BytesIO()
    Image.new("RGB", (256, 256), (200, 0, 0)).save(whole, "JPEG")
    (tmp_path / "tex.jpg").write_bytes(whole.getvalue()[:-200])
    out = tmp_path / "out" / "square.glb"
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(out)], timeout=300)
    assert proc.returncode == 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "is damaged (cut short?)" in proc.stderr, proc.stderr[-2000:]
    assert not out.exists()


@pytest.mark.parametrize("fifo", ["tex.png", "square.mtl"])
def test_a_fifo_the_import_would_read_is_refused_not_waited_on(tmp_path, fifo):
    model = _square_model(tmp_path, "square", "tex.png", (200, 0, 0))
    (tmp_path / fifo).unlink()
    os.mkfifo(tmp_path / fifo)
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(tmp_path / "out.glb")], timeout=120)
    assert proc.returncode == 1 and "is not a regular file (a FIFO" in proc.stderr, proc.stderr[-2000:]


def test_an_output_named_as_an_input_texture_is_refused(tmp_path):
    """The OBJ's texture (PNG bytes) is named tex.glb, and OUT is that file."""
    model = _square_model(tmp_path, "square", "tex.glb", (200, 0, 0))
    before = _digest(tmp_path)
    proc = run_blender(["--python", str(BATCH), "--", str(model), str(tmp_path / "tex.glb")], timeout=300)
    assert proc.returncode == 1 and "would overwrite the input file" in proc.stderr, proc.stderr[-2000:]
    assert _digest(tmp_path) == before


def test_an_importer_that_breaks_on_the_file_is_said_to(tmp_path):
    """Blender's glTF importer raises a bare IndexError on a file whose index
    lies out of range: the message says the importer broke on the file."""
    source = H.ASSIMP / "glTF2" / "IndexOutOfRange" / "IndexOutOfRange.gltf"
    proc = subprocess.run([sys.executable, str(BATCH), str(source), str(tmp_path / "o.glb")], capture_output=True,
                          text=True, timeout=300)
    last = proc.stderr.strip().splitlines()[-1]
    assert proc.returncode == 1 and f"{source}: Blender's importer failed: " in last, last
    assert "Error:" in last and "the importer broke on the file" in last, last
    assert not (tmp_path / "o.glb").exists()


@pytest.mark.parametrize("source, target, message", [
    ("tetra", "o.fbx", "unsupported output format '.fbx'"), ("tetra", "o", "unsupported output format ''"),
    ("model.stl", "o.glb", "unsupported input format '.stl'")])
def test_a_format_the_batch_cannot_take_is_a_usage_error(tmp_path, source, target, message):
    source = H.model_path(source) if source == "tetra" else str(tmp_path / source)
    proc = subprocess.run([sys.executable, str(BATCH), source, str(tmp_path / target)], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2 and message in proc.stderr and "Traceback" not in proc.stderr, proc.stderr


def test_an_unwritable_report_path_fails_before_the_work(tmp_path):
    blocker = tmp_path / "file.txt"
    blocker.write_text("not a folder")
    out = tmp_path / "o.glb"
    t = time.perf_counter()
    proc = subprocess.run([sys.executable, str(BATCH), H.model_path("tetra"), str(out),
                           "--report", str(blocker / "r.json")], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 2 and "--report" in proc.stderr and "Traceback" not in proc.stderr, proc.stderr
    assert not out.exists()
    assert time.perf_counter() - t < 60


@pytest.mark.parametrize("runner", ["blender34", "bpy45"])
def test_ctrl_c_cancels_and_exits_130(tmp_path, runner):
    out_dir = tmp_path / "out"
    args = [H.model_path("smithsonian"), str(out_dir / "scan.obj"), "--report", str(tmp_path / "r.json")]
    if runner == "blender34":
        cmd = [BLENDER, "--background", "--factory-startup", "--python-exit-code", "1", "--python", str(BATCH), "--"]
    else:
        cmd = [sys.executable, str(BATCH)]
    proc = subprocess.Popen(cmd + args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # The scratch folder appears once the model is imported: the native work runs next.
    deadline = time.monotonic() + 300
    while not any(p.name.startswith(".atlas_defrag_") for p in out_dir.glob(".*")) and proc.poll() is None:
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.05)
    time.sleep(1.0)
    t = time.monotonic()
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout[-2000:] + stderr[-2000:]
    assert time.monotonic() - t < 30
    assert "interrupted" in stderr, stderr[-2000:]
    assert _left_in(out_dir) == []
    assert '"status": "cancelled"' in (tmp_path / "r.json").read_text()


def test_a_python3_without_numpy_on_path_does_not_break_blender(tmp_path):
    """python3 batch.py --out-dir from a virtualenv: Blender must not take its
    Python from that python3 (which has no numpy)."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    env = dict(os.environ, BLENDER=BLENDER, PATH=f"{venv / 'bin'}{os.pathsep}{os.environ['PATH']}",
               VIRTUAL_ENV=str(venv))
    out = tmp_path / "out"
    proc = subprocess.run([str(venv / "bin" / "python3"), str(BATCH), "--out-dir", str(out), "--jobs", "1",
                           H.model_path("tetra")], capture_output=True, text=True, timeout=900, env=env)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert (out / "teTra-Mk5-miniature-model.glb").is_file()


def test_ctrl_c_in_the_many_models_form_stops_every_model(tmp_path):
    """SIGINT to the parent alone: it passes it on to the Blender running,
    starts no other and exits 130, leaving no output."""
    out_dir = tmp_path / "out"
    env = dict(os.environ, BLENDER=BLENDER)
    scans = [H.model_path("smithsonian"), H.model_path("tetra")]  # one model given twice is done once
    proc = subprocess.Popen([sys.executable, str(BATCH), "--out-dir", str(out_dir), "--jobs", "1", *scans],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    deadline = time.monotonic() + 300
    while not any(p.name.startswith(".atlas_defrag_") for p in out_dir.glob(".*")) and proc.poll() is None:
        assert time.monotonic() < deadline, "the run never started"
        time.sleep(0.05)
    time.sleep(1.0)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stdout[-2000:] + stderr[-2000:]
    assert "0 done" in stdout and "2 interrupted" in stdout, stdout
    assert [p for p in _left_in(out_dir) if not p.endswith(".report.json")] == []
