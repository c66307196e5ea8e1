"""PLY scans read by atlas_defrag.ply_io (the command-line entry and the batch): the two ways scanning
pipelines store UVs, both byte orders and ASCII, polygons, and broken files."""
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

CLI = Path(__file__).resolve().parent.parent / "tools" / "defrag_scan.py"


def _header(fmt, vertices, faces, vertex_props, face_props, textures):
    lines = ["ply", f"format {fmt} 1.0", *(f"comment TextureFile {t}" for t in textures),
             f"element vertex {vertices}", *(f"property {p}" for p in vertex_props),
             f"element face {faces}", *(f"property {p}" for p in face_props), "end_header"]
    return ("\n".join(lines) + "\n").encode()


def write_face_texcoords(path, scan, order="<"):
    """MeshLab and OpenMVS style: shared vertices, 6 UV values per face, texnumber."""
    fmt = "binary_little_endian" if order == "<" else "binary_big_endian"
    vertex = np.asarray(scan.positions, order + "f8")
    face = np.zeros(len(scan.triangles), np.dtype([("n", "u1"), ("i", order + "i4", (3,)), ("m", "u1"),
                                                   ("uv", order + "f4", (6,)), ("tex", order + "i4")]))
    face["n"], face["i"], face["m"] = 3, scan.triangles, 6
    face["uv"], face["tex"] = scan.uvs.reshape(-1, 6), scan.face_page
    head = _header(fmt, len(vertex), len(face), ["double x", "double y", "double z"],
                   ["list uchar int vertex_indices", "list uchar float texcoord", "int texnumber"],
                   [str(p) for p in scan.page_images])
    path.write_bytes(head + vertex.tobytes() + face.tobytes())


def write_vertex_uvs(path, scan):
    """Blender style, in ASCII: a vertex per face corner with its s and t."""
    corners = scan.positions[scan.triangles].reshape(-1, 3)
    rows = np.hstack([corners, scan.uvs.reshape(-1, 2)])
    faces = np.hstack([np.full((len(scan.triangles), 1), 3), np.arange(3 * len(scan.triangles)).reshape(-1, 3)])
    head = _header("ascii", len(rows), len(faces), ["float x", "float y", "float z", "float s", "float t"],
                   ["list uchar uint vertex_indices"], [str(scan.page_images[0])])
    body = [" ".join(f"{v:.9g}" for v in r) for r in rows] + [" ".join(map(str, f)) for f in faces]
    path.write_bytes(head + ("\n".join(body) + "\n").encode())


@pytest.mark.parametrize("order", ["<", ">"])
def test_face_texcoords_read_back_exactly(scans, tmp_path, order):
    import scan_io

    scan = scans("tetra")
    write_face_texcoords(tmp_path / "scan.ply", scan, order)
    ply = scan_io.load(tmp_path / "scan.ply")
    assert np.array_equal(ply.positions, scan.positions) and np.array_equal(ply.triangles, scan.triangles)
    assert np.array_equal(ply.uvs, scan.uvs.astype(np.float32)) and np.array_equal(ply.face_page, scan.face_page)
    assert np.array_equal(ply.page_sizes, scan.page_sizes)


def test_vertex_uvs_split_at_seams_read_back(scans, tmp_path):
    import scan_io

    scan = scans("tetra")
    write_vertex_uvs(tmp_path / "scan.ply", scan)
    ply = scan_io.load(tmp_path / "scan.ply")
    assert np.allclose(ply.positions[ply.triangles], scan.positions[scan.triangles], rtol=1e-6, atol=1e-9)
    assert np.allclose(ply.uvs, scan.uvs, atol=1e-7)
    textured = scan.face_page >= 0
    assert (ply.face_page[textured] == 0).all()


def test_cli_on_a_ply_scan_matches_the_obj(scans, scan_path, tool_env, tmp_path):
    """The same mesh and UVs through PLY and OBJ: the same charts, and texels within 4%. The PLY holds
    the UVs as float32, so the flattening's last digits differ, which may move the packer's pages: the
    same tetra with its corners listed from the second one packs into 2.7% more texels, with float32
    UVs into 1.4-3.7% more (bench/README.md, session 28)."""
    write_face_texcoords(tmp_path / "tetra.ply", scans("tetra"))
    outs = []
    for source in (scan_path("tetra"), tmp_path / "tetra.ply"):
        run = subprocess.run([sys.executable, str(CLI), str(source), str(tmp_path / source.suffix[1:])],
                             capture_output=True, text=True, timeout=300, env=tool_env)
        assert run.returncode == 0, run.stderr
        outs.append([ln for ln in run.stdout.splitlines() if ln.split()[:1] in (["charts"], ["texels"])])
    assert len(outs[0]) == len(outs[1]) == 2
    # Whether a chart is repaired (over 1% of it below half density) can turn on those digits too.
    assert outs[0][0].split("; density repairs")[0] == outs[1][0].split("; density repairs")[0]
    texels = [int(out[1].split("->")[1].split()[0].replace(",", "")) for out in outs]
    assert abs(texels[1] - texels[0]) <= 0.04 * texels[0], outs
    assert (tmp_path / "ply" / "tetra_defrag.obj").exists()


def test_polygons_of_several_sizes_are_fanned(tmp_path):
    from atlas_defrag import ply_io

    data = _header("ascii", 5, 3, ["float x", "float y", "float z", "float u", "float v"],
                   ["list uchar int vertex_index"], []) + (
        b"0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n2 2 0 1 1\n4 0 1 2 3\n3 1 4 2\n2 0 1\n")
    mesh = ply_io.read(data)
    assert mesh.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]]
    assert mesh.uvs[2].tolist() == [[1, 0], [1, 1], [1, 1]]
    assert mesh.texnumber.tolist() == [0, 0, 0] and mesh.textures == []


def test_binary_polygons_of_several_sizes_are_fanned():
    import struct

    from atlas_defrag import ply_io

    head = _header("binary_big_endian", 5, 2, ["float x", "float y", "float z"], ["list uchar int vertex_indices"], [])
    vertices = struct.pack(">15f", 0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 2, 2, 0)
    faces = struct.pack(">B4i", 4, 0, 1, 2, 3) + struct.pack(">B3i", 3, 1, 4, 2)
    with_edges = head.replace(b"end_header", b"element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header")
    mesh = ply_io.read(with_edges + vertices + faces + struct.pack(">2i", 0, 1))  # an element after the faces
    assert mesh.triangles.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 2]] and mesh.uvs is None
    with pytest.raises(ValueError, match="ends inside its 'face' element"):
        ply_io.read(head + vertices + faces[:-1])


@pytest.mark.parametrize("body, message", [
    (b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n-1\n", "claims -1.0 values"),
    (b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\ninf 0 2 3\n", "claims inf values"),
    (b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n", "ends inside its 'face' element"),
])
def test_lists_of_impossible_length_are_refused(body, message):
    from atlas_defrag import ply_io

    head = _header("ascii", 4, 2, ["float x", "float y", "float z"], ["list uchar int vertex_indices"], [])
    with pytest.raises(ValueError, match=message):
        ply_io.read(head + body)


def test_counts_beyond_the_file_end_at_once():
    """A header claiming billions of rows fails on the file's size, without reading row by row."""
    import time

    from atlas_defrag import ply_io

    for fmt, body in (("ascii", b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"), ("binary_little_endian", bytes(40))):
        head = _header(fmt, 4000000000, 1, ["float x", "float y", "float z"], ["list uchar int vertex_indices"], [])
        start = time.perf_counter()
        with pytest.raises(ValueError, match="ends inside its 'vertex' element"):
            ply_io.read(head + body)
        assert time.perf_counter() - start < 1
    with pytest.raises(ValueError, match="bad header line 'element vertex -1'"):
        ply_io.read(_header("ascii", -1, 0, ["float x"], ["list uchar int vertex_indices"], []))


@pytest.mark.parametrize("body, message", [
    (b"0 0 0 0 0\n1 0 0 1 0\nnan 1 0 1 1\n3 0 1 2 6 0 0 1 0 1 1\n", "vertex position is not a finite number"),
    (b"0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n3 0 1 2 6 0 0 1 inf 1 1\n", "texture coordinate is not a finite number"),
    (b"0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 nan\n3 0 1 2 6 0 0 1 0 1 1\n", None),  # per-vertex UVs not read
])
def test_values_that_are_no_finite_numbers_are_refused(body, message):
    """Blender's mesh validation would make zeros of them without a word."""
    from atlas_defrag import ply_io

    head = _header("ascii", 3, 1, ["float x", "float y", "float z", "float u", "float v"],
                   ["list uchar int vertex_indices", "list uchar float texcoord"], [])
    if message is None:
        assert np.isfinite(ply_io.read(head + body).uvs).all()
        return
    with pytest.raises(ValueError, match=message):
        ply_io.read(head + body)


def test_a_vertex_no_face_uses_may_be_no_number():
    """Point-cloud tools leave such vertices; the mesh never reads them."""
    from atlas_defrag import ply_io

    head = _header("ascii", 4, 1, ["float x", "float y", "float z"], ["list uchar int vertex_indices"], [])
    mesh = ply_io.read(head + b"0 0 0\n1 0 0\n1 1 0\nnan nan nan\n3 0 1 2\n")
    assert mesh.triangles.tolist() == [[0, 1, 2]]


def test_faces_without_two_values_per_corner_are_left_untextured():
    from atlas_defrag import ply_io

    head = _header("ascii", 4, 3, ["float x", "float y", "float z"],
                   ["list uchar int vertex_indices", "list uchar float texcoord"], ["t.png"])
    head = head.replace(b"comment TextureFile t.png\n", b"comment TextureFile t.png\ncomment not the end_header\n")
    mesh = ply_io.read(head + b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 6 0 0 1 0 1 1\n3 0 2 3 0\n"
                       b"4 0 1 2 3 8 0 0 .5 0 .5 .5 0 .5\n")
    assert mesh.texnumber.tolist() == [0, -1, 0, 0] and mesh.uvs[1].tolist() == [[0, 0]] * 3
    assert mesh.uvs[0].tolist() == [[0, 0], [1, 0], [1, 1]] and mesh.uvs[3].tolist() == [[0, 0], [.5, .5], [0, .5]]
    assert mesh.notes == ["texcoord lists without two values per corner leave 1 face(s) untextured"], mesh.notes


def test_texture_numbers_the_header_has_no_file_for_are_named():
    """A quad counts once, as the face the file gave; -1 is how OpenMVS marks a face without texture."""
    from atlas_defrag import ply_io

    head = _header("ascii", 4, 3, ["float x", "float y", "float z"],
                   ["list uchar int vertex_indices", "int texnumber"], ["a.png", "b.png"])
    mesh = ply_io.read(head + b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 2\n4 0 1 2 3 2\n3 0 2 3 -1\n")
    assert mesh.notes == ["texture numbers outside the header's 2 TextureFile line(s) (0..1) leave 2 face(s) "
                          "untextured"], mesh.notes
    assert ply_io.read(head.replace(b"int texnumber", b"uchar texnumber").replace(b"comment TextureFile b.png\n", b"")
                       + b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2 0\n4 0 1 2 3 0\n3 0 2 3 0\n").notes == []


@pytest.mark.parametrize("cut, message", [
    (lambda d: d[:-7], "ends inside its 'face' element"),
    (lambda d: d.replace(b"3 0 1 2", b"3 0 1 9"), "outside 0..3"),
    (lambda d: d.replace(b"1 1 0\n", b"1 x 0\n"), "not a number"),
    (lambda d: d.replace(b"format ascii", b"format utf8"), "unsupported PLY format"),
    (lambda d: d.replace(b"end_header", b"end"), "not a PLY file"),
    (lambda d: d.replace(b"element face 2", b"element face 1"), "holds 4 values more than its header declares"),
    (lambda d: d.replace(b"element vertex 4", b"element vertex 3"), "more than its header declares"),
    (lambda d: d.replace(b"3 0 1 2", b"3 0 1.5 2"), "an integer, but the body gives a fraction"),
    (lambda d: d.replace(b"3 0 2 3", b"2.5 0 2 3"), "claims 2.5 values"),
    (lambda d: d.replace(b"element face 2", b"element face \xb2"), "bad header line"),  # a superscript two
    (lambda d: d.replace(b"property float x", b"property list uchar float x").replace(b"0 0 0\n", b"1 0 0 0\n", 1)
     .replace(b"\n1 0 0\n", b"\n1 1 0 0\n").replace(b"1 1 0\n", b"1 1 1 0\n").replace(b"0 1 0\n", b"1 0 1 0\n"),
     "property 'x' must be a single value"),
])
def test_broken_files_say_what_is_wrong(tmp_path, cut, message):
    from atlas_defrag import ply_io

    data = _header("ascii", 4, 2, ["float x", "float y", "float z"], ["list uchar int vertex_indices"], []) + (
        b"0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n")
    assert len(ply_io.read(data).triangles) == 2
    with pytest.raises(ValueError, match=message):
        ply_io.read(cut(data))


def test_cli_names_a_ply_without_texture(tool_env, tmp_path):
    path = tmp_path / "bare.ply"
    path.write_bytes(_header("ascii", 3, 1, ["float x", "float y", "float z"], ["list uchar int vertex_indices"],
                             []) + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    run = subprocess.run([sys.executable, str(CLI), str(path), str(tmp_path / "out")],
                         capture_output=True, text=True, timeout=60, env=tool_env)
    assert run.returncode == 1 and "no face uses an image texture" in run.stderr


def _coloured_square(fmt):
    """Two triangles whose four vertices carry uchar colours (alpha on none),
    with per-vertex UVs, in ASCII or binary."""
    props = ["float x", "float y", "float z", "float s", "float t", "uchar red", "uchar green", "uchar blue"]
    rows = [(0, 0, 0, 0, 0, 255, 0, 0), (1, 0, 0, 1, 0, 0, 255, 0), (1, 1, 0, 1, 1, 0, 0, 255),
            (0, 1, 0, 0, 1, 128, 128, 128)]
    head = _header(fmt, 4, 2, props, ["list uchar int vertex_indices"], [])
    if fmt == "ascii":
        return head + b"".join(" ".join(map(str, r)).encode() + b"\n" for r in rows) + b"3 0 1 2\n3 0 2 3\n"
    vertex = np.array([r[:5] for r in rows], "<f4")
    colour = np.array([r[5:] for r in rows], "u1")
    body = b"".join(v.tobytes() + c.tobytes() for v, c in zip(vertex, colour))
    faces = np.array([[3, 0, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0], [3, 0, 0, 0, 0, 2, 0, 0, 0, 3, 0, 0, 0]], "u1")
    return head + body + faces.tobytes()


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_vertex_colours_are_read_at_their_types_scale(fmt, tmp_path):
    """uchar colours come out in 0..1 whether ASCII (read as floats) or
    binary, alpha 1 when the file has none; the command line, which does not
    write them, says so."""
    import scan_io
    from atlas_defrag import ply_io

    data = _coloured_square(fmt)
    mesh = ply_io.read(data)
    expected = np.array([[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [128, 128, 128, 255]]) / 255
    assert np.allclose(mesh.colours, expected)
    (tmp_path / "square.ply").write_bytes(data)
    assert any("vertex colours" in w for w in scan_io.load(tmp_path / "square.ply").warnings)


def test_a_sixteen_bit_map_is_named_in_a_warning(scans, scan_path, tmp_path):
    """The command line reads and writes 8 bits a channel: a 16-bit PNG is rounded, and it says so."""
    import shutil

    from PIL import Image

    import scan_io

    source = Path(scan_path("tetra"))
    shutil.copytree(source.parent, tmp_path / "tetra")
    texture = next((tmp_path / "tetra" / "textures").glob("*.jpg"))
    pixels = np.asarray(Image.open(texture).convert("L")).astype(np.uint16) * 257
    Image.fromarray(pixels).save(texture, "PNG")  # a 16-bit grey PNG under the old name
    assert Image.open(texture).mode.startswith("I;16")
    warnings = scan_io.load(tmp_path / "tetra" / source.name).warnings
    assert any("16 bits" in w and texture.name in w for w in warnings), warnings
    assert not any("16 bits" in w for w in scan_io.load(source).warnings)


def test_binary_counts_that_lie_are_refused_and_a_last_line_end_is_not():
    from atlas_defrag import ply_io

    head = _header("binary_little_endian", 3, 1, ["float x", "float y", "float z"],
                   ["list uchar int vertex_indices"], [])
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], "<f4").tobytes()
    face = b"\x03" + np.array([0, 1, 2], "<i4").tobytes()
    assert len(ply_io.read(head + vertices + face + b"\n").triangles) == 1
    with pytest.raises(ValueError, match="holds 13 bytes more than its header declares"):
        ply_io.read(head + vertices + face + face)


def test_texture_names_in_utf8_or_from_another_machine_are_found(tmp_path):
    """Writers put file names in the header as UTF-8; a Windows path names the file beside the PLY,
    in double quotes or not."""
    from atlas_defrag import ply_io

    (tmp_path / "t\u00ebx ture.png").write_bytes(b"")
    (tmp_path / "b.png").write_bytes(b"")
    head = _header("ascii", 3, 2, ["float x", "float y", "float z"],
                   ["list uchar int vertex_indices", "int texnumber"], ["t\u00ebx ture.png", '"C:\\scans\\b.png"'])
    mesh = ply_io.read(head + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0\n3 0 2 1 1\n")
    found, per_face, missing = ply_io.face_textures(mesh, str(tmp_path))
    assert [Path(f).name for f in found] == ["t\u00ebx ture.png", "b.png"] and missing == []
    assert per_face.tolist() == [0, 1]


def test_a_texture_name_in_latin1_finds_the_file_of_those_bytes(tmp_path):
    """Older Windows writers put the file name's own bytes in the header, not
    UTF-8: the file of those bytes is found, else (a file system whose names are
    Unicode, or a copy that turned them into UTF-8) the file of that name."""
    from atlas_defrag import ply_io

    (tmp_path / os.fsdecode(b"caf\xe9.png")).write_bytes(b"")
    (tmp_path / "caf\u00e9 2.png").write_bytes(b"")
    head = _header("ascii", 3, 2, ["float x", "float y", "float z"],
                   ["list uchar int vertex_indices", "int texnumber"], ["X", "Y"])
    head = head.replace(b"TextureFile X", b"TextureFile caf\xe9.png").replace(b"TextureFile Y", b"TextureFile caf\xe9 2.png")
    mesh = ply_io.read(head + b"0 0 0\n1 0 0\n0 1 0\n3 0 1 2 0\n3 0 2 1 1\n")
    found, per_face, missing = ply_io.face_textures(mesh, str(tmp_path))
    assert [os.fsencode(Path(f).name) for f in found] == [b"caf\xe9.png", "caf\u00e9 2.png".encode()], found
    assert missing == [] and per_face.tolist() == [0, 1]


def test_vertex_normals_are_kept_for_the_command_line(tmp_path):
    """nx ny nz of the vertices reach the scan as corner normals, which the
    command line writes back; a file without them has none."""
    import scan_io

    head = _header("ascii", 3, 1, ["float x", "float y", "float z", "float nx", "float ny", "float nz",
                                   "float s", "float t"], ["list uchar int vertex_indices"], [])
    rows = b"0 0 0 0 0 1 0 0\n1 0 0 0 0.6 0.8 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n"
    (tmp_path / "shaded.ply").write_bytes(head + rows)
    scan = scan_io.load(tmp_path / "shaded.ply")
    assert scan.normals[scan.normal_index[0]].tolist() == [[0, 0, 1], [0, 0.6, 0.8], [0, 0, 1]]
    (tmp_path / "square.ply").write_bytes(_coloured_square("ascii"))
    assert scan_io.load(tmp_path / "square.ply").normals is None
    (tmp_path / "nan.ply").write_bytes(head + rows.replace(b"0 0.6 0.8", b"nan 0.6 0.8"))
    assert scan_io.load(tmp_path / "nan.ply").normals is None  # its one face names a normal that is no vector
    head = _header("ascii", 3, 1, ["float x", "float y", "float z", "list uchar float nx", "float ny", "float nz"],
                   ["list uchar int vertex_indices"], [])  # a list is no normal: left out, the file read
    (tmp_path / "listed.ply").write_bytes(head + b"0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n0 1 0 1 0 0 1\n3 0 1 2\n")
    assert scan_io.load(tmp_path / "listed.ply").normals is None
