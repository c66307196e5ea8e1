"""The batch entry's check of the files an export wrote (no Blender needed):
a file cut short is caught from its ends, without reading large images whole."""
import json
import os
import struct
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from atlas_defrag import batch, mtl_text, png_files

CLI = Path(__file__).resolve().parent.parent / "tools" / "defrag_scan.py"


def _glb(body: bytes, declared_extra: int = 0) -> bytes:
    total = 12 + len(body)
    return b"glTF" + struct.pack("<II", 2, total + declared_extra) + body


@pytest.fixture()
def png_bytes():
    pixels = np.arange(4 * 5 * 3, dtype=np.uint8).reshape(4, 5, 3)
    return png_files.encode_png(pixels)


def test_whole_files_pass(tmp_path, png_bytes):
    (tmp_path / "a.png").write_bytes(png_bytes)
    (tmp_path / "a.glb").write_bytes(_glb(b"\0" * 20))
    (tmp_path / "a.exr").write_bytes(b"\x76\x2f\x31\x01" + b"\0" * 40)
    for name in ("a.png", "a.glb", "a.exr"):
        assert batch._file_problem(str(tmp_path / name), None) == "", name


def test_files_cut_short_are_caught(tmp_path, png_bytes):
    (tmp_path / "cut.png").write_bytes(png_bytes[: len(png_bytes) // 2])
    (tmp_path / "cut.glb").write_bytes(_glb(b"\0" * 20, declared_extra=100))
    (tmp_path / "tiny.glb").write_bytes(b"glTF\x02")
    (tmp_path / "bad.exr").write_bytes(b"\0" * 40)
    (tmp_path / "empty.png").write_bytes(b"")
    assert batch._file_problem(str(tmp_path / "cut.png"), None) == "not a complete PNG"
    assert batch._file_problem(str(tmp_path / "cut.glb"), None) == "shorter than its header says"
    assert batch._file_problem(str(tmp_path / "tiny.glb"), None) == "shorter than its header says"
    assert batch._file_problem(str(tmp_path / "bad.exr"), None) == "not an OpenEXR file"
    assert batch._file_problem(str(tmp_path / "empty.png"), None) == "empty"
    assert batch._file_problem(str(tmp_path / "missing.png"), None) == "missing"


OBJ = b"# made by a test\nmtllib scan.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\nf 3/1 2/1 1/1\n"


def test_obj_faces_counted_and_cut_caught(tmp_path):
    (tmp_path / "whole.obj").write_bytes(OBJ)
    (tmp_path / "cut.obj").write_bytes(OBJ[:-14])
    assert batch._file_problem(str(tmp_path / "whole.obj"), 2) == ""
    assert batch._file_problem(str(tmp_path / "whole.obj"), 3) == "2 of 3 faces"
    assert batch._file_problem(str(tmp_path / "cut.obj"), 2) == "1 of 2 faces"


def test_obj_material_libraries_found_and_checked(tmp_path):
    (tmp_path / "scan.obj").write_bytes(b"mtllib first.mtl\r\n" + OBJ + b"usemtl a\nusemtl b c\nusemtl \n"
                                        b"  mtllib  last.mtl\n# mtllib not.mtl")
    names = {p.split("/")[-1] for p in batch._input_files(str(tmp_path / "scan.obj"))[0]}
    assert names == {"scan.obj", "first.mtl", "scan.mtl", "last.mtl"}
    (tmp_path / "spaced.obj").write_bytes(b"mtllib my scan.mtl\n" + OBJ)
    names = {p.split("/")[-1] for p in batch._input_files(str(tmp_path / "spaced.obj"))[0]}
    assert names == {"spaced.obj", "my", "scan.mtl", "my scan.mtl", "spaced.mtl"}  # spaced.mtl: read by default
    (tmp_path / "a.gltf").write_text('{"buffers": [{"uri": "my%20scan.bin"}], "images": [{"uri": "data:x"}]}')
    names = {p.split("/")[-1] for p in batch._input_files(str(tmp_path / "a.gltf"))[0]}
    assert names == {"a.gltf", "my scan.bin"}
    for lib in ("first.mtl", "scan.mtl"):
        (tmp_path / lib).write_bytes(b"newmtl a\nmap_Kd -bm 0.5 -s 1 1 a b.png\n")
    images = ["a b.png", "n.png", "ao.png"]
    with pytest.raises(batch.BatchError, match="last.mtl is missing"):
        batch._verify_obj_references(str(tmp_path), "scan.obj", images)
    (tmp_path / "last.mtl").write_bytes(b"newmtl b c\nmap_Bump -bm 1.0 n.png")
    with pytest.raises(batch.BatchError, match="last.mtl is cut short"):
        batch._verify_obj_references(str(tmp_path), "scan.obj", images)
    (tmp_path / "last.mtl").write_bytes(b"newmtl x\n")
    with pytest.raises(batch.BatchError, match="do not define b c"):
        batch._verify_obj_references(str(tmp_path), "scan.obj", images)
    # Whole: the images no map names (an occlusion map, which OBJ cannot carry) come back.
    (tmp_path / "last.mtl").write_bytes(b"newmtl b c\nmap_Bump -bm 1.0 n.png\n")
    assert batch._verify_obj_references(str(tmp_path), "scan.obj", images) == ["ao.png"]
    # Cut at a line end before the last material's map_Kd: whole-looking, but a base colour goes unnamed.
    (tmp_path / "last.mtl").write_bytes(b"newmtl b c\nKd 1 1 1\n")
    with pytest.raises(batch.BatchError, match="do not name n.png"):
        batch._verify_obj_references(str(tmp_path), "scan.obj", images, {"a b.png", "n.png"})


@pytest.mark.parametrize("arguments, name", [
    ("tex.png", "tex.png"), ("-o 0.1 0.2 tex.png", "tex.png"), ("-s 1 2 3 my  scan.png", "my  scan.png"),
    ("-bm 1.0 2024 scan.png", "2024 scan.png"), ("-s 2 2024.png", "2024.png"),
    ("-clamp on -imfchan l t.png", "t.png"), ("-bm 1.0", "1.0"), ("", "")])
def test_map_statements_name_their_file_after_the_options(arguments, name):
    assert mtl_text.map_file(arguments) == name


def test_a_report_may_not_replace_the_input_or_the_output(tmp_path):
    model, out = tmp_path / "in.obj", tmp_path / "out.obj"
    model.write_bytes(b"mtllib in.mtl\n" + OBJ)
    for report in (model, tmp_path / "in.mtl", out, tmp_path / "out.mtl"):
        assert "would overwrite" in batch._report_path_problem(str(report), str(model), str(out)), report
    assert batch._report_path_problem(str(tmp_path / "r.json"), str(model), str(out)) == ""


def test_a_run_into_its_input_folder_takes_no_output_for_an_input(tmp_path):
    """An earlier run's output is known by the report beside it naming another
    input, not by its name: rock_2.obj, and a.glb beside a.obj, may be scans
    of their own (both were dropped, and the run said 0 done, exit 0). A
    model given twice, by itself and in its folder, is done once. An earlier
    run's OBJ output is known so as well in a run writing GLB, and a model of
    the same name in another format is not taken for it."""
    for name in ("a.obj", "a.glb", "a_2.glb", "b.glb", "rock.obj", "rock_2.obj", "c.obj", "c_2.obj", "c_3.glb",
                 "c_3.obj"):
        (tmp_path / name).write_bytes(b"")
    (tmp_path / "a_2.report.json").write_text(json.dumps({"input": str(tmp_path / "a.obj"),
                                                          "output": str(tmp_path / "a_2.glb")}))
    for stem, ext in (("c_2", "obj"), ("c_3", "glb")):
        (tmp_path / f"{stem}.report.json").write_text(json.dumps({"input": str(tmp_path / "c.obj"),
                                                                  "output": str(tmp_path / f"{stem}.{ext}")}))
    (tmp_path / "rock_2.report.json").write_text("not a report")
    files = batch._expand([str(tmp_path), str(tmp_path / "b.glb")])
    kept = batch._without_outputs(files, str(tmp_path))
    assert [p.split("/")[-1] for p in kept if p.split("/")[-1].startswith("c")] == ["c.obj", "c_3.obj"], kept
    kept = [p for p in kept if not p.split("/")[-1].startswith("c")]
    assert [p.split("/")[-1] for p in kept] == ["a.glb", "a.obj", "b.glb", "rock.obj", "rock_2.obj"]
    jobs = batch._output_names(kept, str(tmp_path), "glb")
    # Never onto an input, nor onto another input's earlier output; a.obj's is a_2.glb again (then skipped).
    assert [out.split("/")[-1] for _, out, _ in jobs] == ["a_3.glb", "a_2.glb", "b_2.glb", "rock.glb", "rock_2.glb"]
    # An input moved since its run (its report names a path no longer there) keeps its output's name.
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "a.report.json").write_text(json.dumps({"input": "/moved/away/a.obj"}))
    assert batch._output_names([str(tmp_path / "a.obj")], str(tmp_path / "out"), "glb")[0][1].endswith("/out/a.glb")


def test_an_output_folder_that_cannot_be_made_is_one_line(tmp_path, capsys):
    (tmp_path / "a_file").write_text("")
    code = batch.main_multi(["--out-dir", str(tmp_path / "a_file" / "out"), "--blender", sys.executable,
                             str(tmp_path / "x.obj")])
    err = capsys.readouterr().err
    assert code == 2 and "cannot make the output folder" in err and "Traceback" not in err, err


def test_the_many_models_form_names_a_missing_blender(tmp_path, capsys):
    code = batch.main_multi(["--out-dir", str(tmp_path / "out"), "--blender", str(tmp_path / "no" / "blender"),
                             str(tmp_path / "x.obj")])
    assert code == 2 and "Blender not found" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_operator_errors_come_without_their_traceback():
    wrapped = RuntimeError(
        "Error: Python: Traceback (most recent call last):\n"
        '  File "/usr/share/blender/scripts/addons/io_scene_gltf2/__init__.py", line 1245, in execute\n'
        "    return self.import_gltf2(context)\n"
        "RuntimeError: internal error setting the array\n\n"
        "Location: /usr/share/blender/scripts/modules/bpy/ops.py:113\n")
    assert batch._operator_error(wrapped) == "RuntimeError: internal error setting the array"
    plain = RuntimeError("Error: Couldn't parse glTF. Check that the file is valid\n\nLocation: ops.py:113")
    assert batch._operator_error(plain) == "Error: Couldn't parse glTF. Check that the file is valid"
    dotted = RuntimeError("Error: Python: Traceback (most recent call last):\n  File \"x.py\", line 3, in f\n"
                          "struct.error: unpack_from requires a buffer of at least 4 bytes\n\nLocation: ops.py:113")
    assert batch._operator_error(dotted) == "struct.error: unpack_from requires a buffer of at least 4 bytes"


MESH = types.SimpleNamespace(type="MESH", data=types.SimpleNamespace(polygons=[0, 1]))


def replaceable(dst) -> set:
    """What run_one lets the moves replace at dst: the earlier output's libraries and their images."""
    libraries = batch._libraries_named_by(str(dst))
    return libraries | batch._images_named_by(str(dst), libraries)


def fake_export(mtl_name: str, mtl: bytes, images=()):
    """An export_model stand-in: the OBJ (naming mtl_name and using material
    a), its MTL and the (name, bytes) images, beside it."""
    def export(path, objects):
        folder = os.path.dirname(path)
        with open(path, "wb") as f:
            f.write(b"mtllib " + mtl_name.encode() + b"\nusemtl a\n" + OBJ)
        for name, data in [(mtl_name, mtl)] + list(images):
            with open(os.path.join(folder, name), "wb") as f:
                f.write(data)
    return export


def earlier_output(tmp_path, mtl: bytes, files=()):
    """tmp_path/out holding an earlier OBJ output scan.obj, its MTL and the
    (name, bytes) files beside it."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "scan.obj").write_bytes(b"mtllib scan.mtl\n" + OBJ)
    (out / "scan.mtl").write_bytes(mtl)
    for name, data in files:
        (out / name).write_bytes(data)
    return out


def test_a_move_that_fails_puts_the_previous_run_back(tmp_path, monkeypatch):
    """A run over an earlier OBJ output that fails while moving its files in
    leaves the earlier model whole: its MTL and images as they were."""
    out = earlier_output(tmp_path, b"newmtl a\nmap_Kd scan_tex.png\n", [("scan_tex.png", b"old pixels")])
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    tmp = tmp_path / "tmp"
    tmp.mkdir()

    export = fake_export("scan.mtl", b"newmtl a\nmap_Kd scan_tex.png\n",
                         [("scan_tex.png", png_files.encode_png(np.zeros((2, 2, 3), np.uint8)))])
    real_replace = os.replace

    def replace(src, dst):
        if str(dst) == str(out / "scan.obj") and not os.path.basename(src).startswith(".previous_"):
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(batch, "export_model", export)
    monkeypatch.setattr(batch.os, "replace", replace)
    with pytest.raises(OSError):
        batch._export_and_move([MESH], str(tmp), str(out / "scan.obj"), set(), lambda: None,
                               replaceable(out / "scan.obj"))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_an_output_that_is_an_input_by_another_name_is_refused(tmp_path):
    """A hard link stands for what a case-insensitive file system does with
    Scan.obj and scan.obj: two names, one file."""
    model = tmp_path / "Scan.obj"
    model.write_bytes(OBJ)
    os.link(model, tmp_path / "scan.obj")
    with pytest.raises(batch.BatchError, match="would overwrite the input file"):
        batch._refuse_overwriting({str(model)}, [str(tmp_path / "scan.obj")])
    batch._refuse_overwriting({str(model)}, [str(tmp_path / "other.obj")])


def test_quoted_and_default_material_libraries_are_inputs(tmp_path):
    model = tmp_path / "in.obj"
    model.write_bytes(b'mtllib "my scan.mtl"\n' + OBJ)
    files = {os.path.basename(p) for p in batch._input_files(str(model))[0]}
    assert {"my scan.mtl", "in.mtl"} <= files, files  # Blender's importer reads both
    broken = tmp_path / "b.gltf"
    broken.write_text('{"buffers": {}}')
    assert batch._input_files(str(broken))[0] == {str(broken)}


def test_an_mtl_of_another_model_is_never_replaced(tmp_path, monkeypatch):
    """statue.glb written as statue.obj beside the user's statue.mtl (the
    library of statue_lowpoly.obj): refused before the work, and the move
    would not replace it either."""
    (tmp_path / "statue.mtl").write_bytes(b"newmtl user\nmap_Kd user.png\n")
    statue = str(tmp_path / "statue.obj")
    with pytest.raises(batch.BatchError, match="is not the material library of"):
        batch._refuse_foreign_library(statue, batch._libraries_named_by(statue))
    tmp = tmp_path / "tmp"
    tmp.mkdir()

    monkeypatch.setattr(batch, "export_model", fake_export("statue.mtl", b"newmtl a\n"))
    with pytest.raises(batch.BatchError):
        batch._export_and_move([MESH], str(tmp), str(tmp_path / "statue.obj"), set(), lambda: None,
                               replaceable(tmp_path / "statue.obj"))
    assert (tmp_path / "statue.mtl").read_bytes() == b"newmtl user\nmap_Kd user.png\n"
    assert not (tmp_path / "statue.obj").exists()


def test_previous_files_that_cannot_go_back_are_kept_beside(tmp_path, monkeypatch):
    out = earlier_output(tmp_path, b"newmtl a\n", [("scan.mtl.previous", b"the user's")])
    tmp = tmp_path / "tmp"
    tmp.mkdir()

    real_replace = os.replace

    def replace(src, dst):
        if str(src) == str(tmp / "scan.obj") or (str(src).endswith(".previous_scan.mtl") and
                                                 str(dst) == str(out / "scan.mtl")):
            raise OSError(28, "No space left on device")
        real_replace(src, dst)

    monkeypatch.setattr(batch, "export_model", fake_export("scan.mtl", b"newmtl a\n# new\n"))
    monkeypatch.setattr(batch.os, "replace", replace)
    with pytest.raises(batch.PreviousFilesKept, match="scan.mtl.previous1"):
        batch._export_and_move([MESH], str(tmp), str(out / "scan.obj"), set(), lambda: None,
                               replaceable(out / "scan.obj"))
    assert (out / "scan.mtl.previous1").read_bytes() == b"newmtl a\n"
    assert (out / "scan.mtl.previous").read_bytes() == b"the user's"
    assert (out / "scan.obj").read_bytes() == b"mtllib scan.mtl\n" + OBJ


class Killed(BaseException):
    """Stands for a kill: raised where the process would die."""


def test_a_run_killed_while_moving_leaves_no_model_beside_images_it_does_not_match(tmp_path, monkeypatch):
    """Killed after the new image replaced the earlier output's: the earlier
    model must not be left at OUT with it (an existing OUT means a finished
    run); the earlier files wait in the scratch folder, and the next run
    names them."""
    out = earlier_output(tmp_path, b"newmtl a\nmap_Kd scan_tex.png\n", [("scan_tex.png", b"old pixels")])
    tmp = out / ".atlas_defrag_test"
    tmp.mkdir()
    new_png = png_files.encode_png(np.zeros((2, 2, 3), np.uint8))
    real_replace = os.replace

    def replace(src, dst):
        real_replace(src, dst)
        if str(dst) == str(out / "scan_tex.png"):
            raise Killed()

    monkeypatch.setattr(batch, "export_model", fake_export(
        "scan.mtl", b"newmtl a\nmap_Kd scan_tex.png\n", [("scan_tex.png", new_png)]))
    monkeypatch.setattr(batch.os, "replace", replace)
    monkeypatch.setattr(batch, "_restore", lambda kept: [])  # a killed process cleans nothing up
    monkeypatch.setattr(batch, "_remove_quietly", lambda path: None)
    with pytest.raises(Killed):
        batch._export_and_move([MESH], str(tmp), str(out / "scan.obj"), set(), lambda: None,
                               replaceable(out / "scan.obj"))
    assert not (out / "scan.obj").exists()
    assert (tmp / ".previous_scan.obj").read_bytes() == b"mtllib scan.mtl\n" + OBJ
    assert (tmp / ".previous_scan_tex.png").read_bytes() == b"old pixels"
    warnings = batch._interrupted_runs(str(out / "scan.obj"))
    assert len(warnings) == 1 and "scan.obj" in warnings[0] and "scan_tex.png" in warnings[0], warnings
    assert batch._interrupted_runs(str(out / "other.obj")) == []
    # The next run may replace the MTL left beside the missing model: it is that model's.
    batch._refuse_foreign_library(str(out / "scan.obj"), batch._libraries_named_by(str(out / "scan.obj")))


def test_only_scratch_folders_holding_earlier_files_are_named(tmp_path):
    (tmp_path / ".atlas_defrag_empty").mkdir()
    (tmp_path / ".atlas_defrag_new").mkdir()
    (tmp_path / ".atlas_defrag_new" / "scan.obj").write_bytes(OBJ)
    (tmp_path / "scan.obj").write_bytes(OBJ)
    assert batch._interrupted_runs(str(tmp_path / "scan.obj")) == []
    assert batch._interrupted_runs(str(tmp_path / "missing" / "scan.obj")) == []


def test_a_report_replaces_only_an_earlier_report(tmp_path):
    model, out = tmp_path / "in.obj", tmp_path / "out.obj"
    model.write_bytes(b"mtllib in.mtl\n" + OBJ)
    (tmp_path / "in.mtl").write_bytes(b"newmtl a\nmap_Kd tex.png\n")
    (tmp_path / "tex.png").write_bytes(b"\x89PNG pixels")
    assert "is not a report" in batch._report_path_problem(str(tmp_path / "tex.png"), str(model), str(out))
    (tmp_path / "r.json").write_text('{"status": "ok"}')
    assert batch._report_path_problem(str(tmp_path / "r.json"), str(model), str(out)) == ""


def test_the_report_is_written_whole_and_never_over_another_file(tmp_path):
    report = tmp_path / "r.json"
    batch._write_report(str(report), {"status": "ok"})
    assert json.loads(report.read_text()) == {"status": "ok"}
    clash = tmp_path / f"r.json.{os.getpid()}.tmp"
    clash.write_text("the user's")
    with pytest.raises(FileExistsError):
        batch._write_report(str(report), {"status": "error"})
    assert clash.read_text() == "the user's" and json.loads(report.read_text()) == {"status": "ok"}


def test_cached_bytecode_counts_only_when_compiled_from_the_source_as_it_is(tmp_path, monkeypatch):
    """The batch entry writes the bytecode of modules Blender imported before
    it ran unless the cache holds it already: a stale one (the source changed
    since, as after an upgrade) is written again."""
    import py_compile

    monkeypatch.setattr("sys.pycache_prefix", str(tmp_path / "cache"))
    source = tmp_path / "scripts" / "startup_module.py"
    source.parent.mkdir()
    source.write_text("X = 1\n")
    assert not batch._bytecode_current(str(source))
    py_compile.compile(str(source), cfile=batch.importlib.util.cache_from_source(str(source)),
                       invalidation_mode=py_compile.PycInvalidationMode.TIMESTAMP)
    assert batch._bytecode_current(str(source))
    source.write_text("X = 22\n")  # another size
    assert not batch._bytecode_current(str(source))
    py_compile.compile(str(source), cfile=batch.importlib.util.cache_from_source(str(source)),
                       invalidation_mode=py_compile.PycInvalidationMode.TIMESTAMP)
    st = source.stat()
    os.utime(source, (st.st_atime, st.st_mtime - 100))  # same size, older
    assert not batch._bytecode_current(str(source))


def test_the_many_models_form_starts_blender_reading_the_bytecode_cache(monkeypatch):
    monkeypatch.delenv("PYTHONPYCACHEPREFIX", raising=False)
    assert batch._blender_env("blender")["PYTHONPYCACHEPREFIX"] == batch.bytecode_cache_dir()
    monkeypatch.setenv("PYTHONPYCACHEPREFIX", "/elsewhere")
    assert batch._blender_env("blender")["PYTHONPYCACHEPREFIX"] == "/elsewhere"


def test_a_bytecode_cache_that_cannot_be_written_costs_only_time(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setattr("sys.pycache_prefix", str(blocker / "cache"))  # no folder can be made there
    monkeypatch.setattr("sys.dont_write_bytecode", True)
    batch._cache_bytecode()
    assert not (tmp_path / "cache").exists() and blocker.is_file()


def _count_compiles(monkeypatch, fail: bool) -> list:
    calls = []

    def compile_(source, **_):
        calls.append(source)
        if fail:
            raise OSError(28, "No space left on device")
    monkeypatch.setattr(batch.py_compile, "compile", compile_)
    monkeypatch.setattr(batch, "_bytecode_current", lambda source: False)
    monkeypatch.setattr("sys.dont_write_bytecode", True)
    return calls


def test_a_cache_folder_that_takes_no_file_compiles_nothing(tmp_path, monkeypatch):
    """A compile costs as much whether its write succeeds or not: a cache that
    exists but cannot be written to (read-only, owned by another user) would
    make every process compile every start-up module for nothing."""
    calls = _count_compiles(monkeypatch, fail=False)
    monkeypatch.setattr("sys.pycache_prefix", str(tmp_path))

    def refuse(*_, **__):
        raise PermissionError(13, "Permission denied")
    monkeypatch.setattr(batch.tempfile, "TemporaryFile", refuse)
    batch._cache_bytecode()
    assert calls == [] and sys.dont_write_bytecode


def test_the_first_write_that_fails_ends_the_bytecode_cache(tmp_path, monkeypatch):
    calls = _count_compiles(monkeypatch, fail=True)
    monkeypatch.setattr("sys.pycache_prefix", str(tmp_path))
    batch._cache_bytecode()
    assert len(calls) == 1 and sys.dont_write_bytecode
    calls = _count_compiles(monkeypatch, fail=False)
    batch._cache_bytecode()
    assert len(calls) > 1 and not sys.dont_write_bytecode


def test_no_home_no_bytecode_cache(tmp_path, monkeypatch):
    """Without HOME and a passwd entry, expanduser leaves '~' as it is: the
    cache would otherwise land in a folder named '~' under the current one."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.delenv("XDG_CACHE_HOME", raising=False)
    monkeypatch.delenv("PYTHONPYCACHEPREFIX", raising=False)
    monkeypatch.setattr(batch.os.path, "expanduser", lambda path: path)
    monkeypatch.setattr("sys.pycache_prefix", None)
    calls = _count_compiles(monkeypatch, fail=False)
    assert batch.bytecode_cache_dir() == ""
    batch._cache_bytecode()
    assert calls == [] and "PYTHONPYCACHEPREFIX" not in batch._blender_env("blender")
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_the_bytecode_cache_is_written_ends_the_run_as_interrupted(tmp_path, monkeypatch, capsys):
    """The first run compiles Blender's start-up modules for a second or two,
    before the interrupt handler of the job is in place."""
    def interrupted():
        raise KeyboardInterrupt
    monkeypatch.setattr(batch, "_cache_bytecode", interrupted)
    code = batch.main_single([str(tmp_path / "in.obj"), str(tmp_path / "out.glb")])
    assert code == batch.EXIT_INTERRUPTED and "interrupted" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


def test_the_scenes_of_a_gltf_are_counted_for_the_warning(tmp_path):
    """Blender's importer reads the nodes of every scene into one: the run warns when there are several."""
    body = json.dumps({"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}, {"nodes": [1]}]}).encode()
    (tmp_path / "two.gltf").write_bytes(body)
    body += b" " * (-len(body) % 4)
    (tmp_path / "two.glb").write_bytes(_glb(struct.pack("<II", len(body), 0x4E4F534A) + body))
    (tmp_path / "bad.gltf").write_text("[" * 100_000)
    assert batch._gltf_scene_count(str(tmp_path / "two.gltf")) == 2
    assert batch._gltf_scene_count(str(tmp_path / "two.glb")) == 2
    assert batch._gltf_scene_count(str(tmp_path / "bad.gltf")) == 0


def test_sigterm_cancels_like_sigint_also_before_the_token_exists():
    """timeout, kill, GNU parallel and job schedulers send SIGTERM: it killed
    the run midway and left its scratch folder with the images written so far."""
    import signal

    class Token:
        cancelled = False

        def cancel(self):
            self.cancelled = True

    before = signal.getsignal(signal.SIGTERM)
    with batch._Interrupt() as interrupt:
        os.kill(os.getpid(), signal.SIGTERM)
        assert interrupt.caught == "SIGTERM"
        token = Token()
        interrupt.attach(token)  # caught before the token was made: cancelled at once
        assert token.cancelled
    assert signal.getsignal(signal.SIGTERM) is before


def test_a_model_of_many_meshes_that_cannot_be_laid_out_says_so_in_one_short_line():
    reasons = [f"m{k}: Mesh 'm{k}' has no UV map" for k in range(67)]
    text = batch._listed(reasons)
    assert text.count("has no UV map") == 3 and text.endswith("and 64 more meshes")
    assert batch._listed(reasons[:3]) == "; ".join(reasons[:3])


def test_image_format_and_quality_are_checked_before_any_work():
    assert batch._image_format_problem("auto", ".obj") == ""
    assert batch._image_format_problem("jpeg", ".glb") == "" and batch._image_format_problem("webp", ".gltf") == ""
    assert "glTF outputs" in batch._image_format_problem("jpeg", ".obj")
    args = batch.single_parser().parse_args(["in.obj", "out.glb", "--image-format", "jpeg", "--image-quality", "70"])
    assert (args.image_format, args.image_quality) == ("jpeg", 70)
    for bad in ("0", "101", "high"):
        with pytest.raises(SystemExit):
            batch.single_parser().parse_args(["in.obj", "out.glb", "--image-quality", bad])
    many = batch.multi_parser().parse_args(["in.obj", "--out-dir", "o", "--image-format", "webp"])
    assert batch._passthrough(many)[-4:] == ["--image-format", "webp", "--image-quality", "90"]
    assert batch.main_multi(["in.obj", "--out-dir", "o", "--format", "obj", "--image-format", "jpeg"]) == 2


def test_a_pair_of_options_that_conflict_is_refused_before_any_work(tmp_path, capsys, tool_env):
    """fixed_page_size above max_page_size exits 2 as a bad value does, in
    every entry, before a model is read (or a Blender started per model)."""
    import subprocess

    conflict = ["--fixed-page-size", "16384", "--max-page-size", "8192"]
    assert batch.main_single([str(tmp_path / "in.obj"), str(tmp_path / "out.glb")] + conflict) == 2
    assert batch.main_multi([str(tmp_path / "in.obj"), "--out-dir", str(tmp_path / "o")] + conflict) == 2
    assert capsys.readouterr().err.count("fixed_page_size 16384 is larger than max_page_size 8192") == 2
    run = subprocess.run([sys.executable, str(CLI), str(tmp_path / "in.obj"), str(tmp_path / "o")] + conflict,
                         capture_output=True, text=True, timeout=60, env=tool_env)
    assert run.returncode == 2 and "is larger than max_page_size" in run.stderr, run.stderr
    assert list(tmp_path.iterdir()) == []


def _gltf_file(path, materials, images=({"uri": "t.png"},)):
    path.write_text(json.dumps({"asset": {"version": "2.0"}, "images": list(images), "materials": materials}))
    return str(path)


def test_a_gltf_giving_a_rebuilt_material_no_texture_is_refused(tmp_path):
    """Blender's glTF exporter drops the texture of a material it cannot
    export (specular-glossiness) while writing another's: the model would
    come out with one material untextured."""
    textured = {"name": "a", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}
    bare = {"name": "b", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}}
    path = _gltf_file(tmp_path / "m.gltf", [textured, bare])
    batch._require_gltf_images(path, ["new.png"], {"a"})
    with pytest.raises(batch.BatchError, match="the materials b without a texture"):
        batch._require_gltf_images(path, ["new.png"], {"a", "b"})
    with pytest.raises(batch.BatchError, match="none of the new images"):
        batch._require_gltf_images(_gltf_file(tmp_path / "n.gltf", [textured], images=()), ["new.png"], {"a"})


def test_input_images_copied_beside_an_obj_are_checked_by_their_size(tmp_path, png_bytes):
    """A copy of an input image is whole when all its bytes are there, whatever
    they hold (a JPEG named .png, say): it is not checked as a PNG Blender wrote."""
    (tmp_path / "scan.obj").write_bytes(b"mtllib scan.mtl\nusemtl a\n" + OBJ)
    (tmp_path / "scan.mtl").write_bytes(b"newmtl a\nmap_Kd scan_in.png\n")
    jpeg = b"\xff\xd8\xff\xe0" + b"\0" * 60 + b"\xff\xd9"
    (tmp_path / "scan_in.png").write_bytes(jpeg)
    names = ["scan.mtl", "scan_in.png"]
    assert batch._verify_outputs(str(tmp_path), "scan.obj", names, 2, copies={"scan_in.png": len(jpeg)}) == []
    with pytest.raises(batch.BatchError, match="66 of 70 bytes"):
        batch._verify_outputs(str(tmp_path), "scan.obj", names, 2, copies={"scan_in.png": 70})


def test_a_folder_where_the_output_sets_a_file_aside_is_never_moved(tmp_path, monkeypatch):
    """An earlier output's image name taken by a folder: the run fails and
    the folder keeps its files (set aside, it would go with the scratch folder)."""
    out = earlier_output(tmp_path, b"newmtl a\nmap_Kd scan_tex.png\n")
    (out / "scan_tex.png").mkdir()
    (out / "scan_tex.png" / "keep.txt").write_text("mine")
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    new_png = png_files.encode_png(np.zeros((2, 2, 3), np.uint8))
    monkeypatch.setattr(batch, "export_model", fake_export(
        "scan.mtl", b"newmtl a\nmap_Kd scan_tex.png\n", [("scan_tex.png", new_png)]))
    with pytest.raises(batch.BatchError, match="is a folder"):
        batch._export_and_move([MESH], str(tmp), str(out / "scan.obj"), set(), lambda: None,
                               replaceable(out / "scan.obj"))
    assert (out / "scan_tex.png" / "keep.txt").read_text() == "mine"
    assert (out / "scan.obj").read_bytes() == b"mtllib scan.mtl\n" + OBJ
    with pytest.raises(batch.BatchError, match="is a folder"):
        batch._refuse_folders(batch._model_files(str(out / "scan_tex.png")))


@pytest.mark.parametrize("line, file_system", [
    ("FileNotFoundError: [Errno 2] No such file or directory: 'a.bin'", True),
    ("PermissionError: [Errno 13] Permission denied", True),
    ("IndexError: index 255 is out of bounds", False),
    ("Error: Couldn't parse glTF", False)])
def test_an_importer_error_on_a_file_it_could_not_read_is_not_blamed_on_the_format(line, file_system):
    assert batch._file_system_error(line) == file_system
