"""Reads a textured PLY mesh (ASCII or binary, either byte order) into numpy arrays.

Scanning pipelines write UVs in one of two ways, and both are read:
- per face, a list property `texcoord` of 2 values per corner, with an
  optional `texnumber` naming the texture (MeshLab, OpenMVS);
- per vertex, `s t`, `u v`, `texture_u texture_v` or `texture_s texture_t`,
  with vertices split at seams (Blender, many scanner apps).
Textures are the header's `comment TextureFile <name>` lines, in texnumber
order. Polygons are fan-triangulated, as the OBJ reader does. No bpy: the
command-line entry (tools/scan_io.py) reads scans with it too, and the batch
entry through ply_import.
"""
from __future__ import annotations

import os
import struct
import warnings
from dataclasses import dataclass, field

import numpy as np

from .mtl_text import unquoted

_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
          "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
          "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_VERTEX_UV_NAMES = (("s", "t"), ("u", "v"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
# Vertex properties read as one value each.
_SCALARS = {"x", "y", "z", "red", "green", "blue", "alpha"} | {n for pair in _VERTEX_UV_NAMES for n in pair}


@dataclass
class Property:
    name: str
    type: str                 # numpy type code of the value(s), e.g. "f4"
    count_type: str = None    # numpy type code of a list's length; None: a single value


@dataclass
class Element:
    name: str
    count: int
    properties: list = field(default_factory=list)


@dataclass
class PlyMesh:
    positions: np.ndarray     # (V, 3) float64
    triangles: np.ndarray     # (F, 3) int64, fan-triangulated polygons
    uvs: np.ndarray           # (F, 3, 2) float64, v up; None when the file has no UVs
    texnumber: np.ndarray     # (F,) int64, index into textures (0 when the file gives none;
                              # -1 where a face's texcoord list is not two values per corner)
    textures: list            # file names from the header, as written
    colours: np.ndarray = None  # (V, 4) float32 sRGB in 0..1 (alpha 1 when absent); None: no vertex colours
    notes: list = field(default_factory=list)  # faces left untextured by what the file says, in words
    normals: np.ndarray = None  # (V, 3) float64, the vertices' nx ny nz; None when the file has none


def _type(name: str) -> str:
    if name not in _TYPES:
        raise ValueError(f"unknown PLY property type '{name}'")
    return _TYPES[name]


# Past this many bytes without an end_header line, the file is taken as no PLY.
_MAX_HEADER_BYTES = 1 << 20


def _header_lines(data: bytes):
    """(the header's lines after 'ply', offset of the body)."""
    if not data.startswith(b"ply"):
        raise ValueError("not a PLY file (it does not start with 'ply')")
    lines, at = [], data.find(b"\n") + 1
    while 0 < at <= _MAX_HEADER_BYTES:
        newline = data.find(b"\n", at)
        end = len(data) if newline < 0 else newline
        line = data[at:end].decode("latin-1").strip()
        at = end + 1
        if line == "end_header":
            return lines, min(at, len(data))
        lines.append(line)
        if newline < 0:
            break
    raise ValueError("not a PLY file (no 'end_header' line)")


def _utf8(name: str) -> str:
    """A header word read as latin-1, as UTF-8 (writers put file names so); bytes that
    are not UTF-8 (a Latin-1 name) are kept as surrogates, which name that very file."""
    return name.encode("latin-1").decode("utf-8", "surrogateescape")


def readable(name: str) -> str:
    """A header file name for messages: its bytes that are not UTF-8 read as Latin-1, which
    (unlike the surrogates _utf8 keeps) Blender's reports and every terminal can show."""
    raw = name.encode("utf-8", "surrogateescape")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def _element(words: list, line: str) -> Element:
    if len(words) != 3 or not (words[2].isascii() and words[2].isdigit()):
        raise ValueError(f"bad header line '{line}' (element NAME COUNT)")
    return Element(words[1], int(words[2]))


def _property(words: list, line: str) -> Property:
    if words[1:2] == ["list"] and len(words) == 5:
        return Property(words[4], _type(words[3]), _type(words[2]))
    if len(words) == 3 and words[1] != "list":
        return Property(words[2], _type(words[1]))
    raise ValueError(f"bad header line '{line}'")


def parse_header(data: bytes):
    """(format, [Element], texture names, offset of the body)."""
    lines, body = _header_lines(data)
    fmt, elements, textures = None, [], []
    for line in lines:
        words = line.split()
        if not words:
            continue
        if words[0] == "format" and len(words) > 1:
            fmt = words[1]
        elif words[0] == "comment" and len(words) > 2 and words[1].lower() == "texturefile":
            textures.append(_utf8(unquoted(line.split(None, 2)[2])))
        elif words[0] == "element":
            elements.append(_element(words, line))
        elif words[0] == "property":
            if not elements:
                raise ValueError(f"bad header line '{line}' (a property before any element)")
            elements[-1].properties.append(_property(words, line))
    if fmt not in ("ascii", "binary_little_endian", "binary_big_endian"):
        raise ValueError(f"unsupported PLY format '{fmt}'")
    return fmt, elements, textures, body


# Longest list a row may hold (a face of this many corners is no scan's).
_MAX_LIST = 1 << 16


class _ImpossibleList(ValueError):
    """A list length no file can mean: negative, not finite or past _MAX_LIST."""


def _list_length(element: Element, value) -> int:
    """value, a list's length as read from the file, as an int; _ImpossibleList otherwise."""
    if not (np.isfinite(value) and 0 <= value <= _MAX_LIST and value == int(value)):
        raise _ImpossibleList(f"a list of its '{element.name}' element claims {value} values")
    return int(value)


def _starts(counts: np.ndarray) -> np.ndarray:
    """Where each of consecutive runs of these lengths starts."""
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)

# An element's values: per scalar property an (N,) array; per list property
# (flat values, counts), the values of all rows one after another.

def _binary_rows(element: Element, data: bytes, at: int, order: str):
    """(values, offset after the element). Lists as long as the first row's
    are read as one block; rows of other lengths, record by record."""
    least_row = sum(np.dtype(p.count_type or p.type).itemsize for p in element.properties)
    if element.count * least_row > len(data) - at:
        raise ValueError("past the end")
    lengths = []
    probe = at
    for p in element.properties:
        if p.count_type is None:
            probe += np.dtype(p.type).itemsize
        else:
            n = _list_length(element, np.frombuffer(data, order + p.count_type, 1, probe)[0] if element.count else 0)
            lengths.append(n)
            probe += np.dtype(p.count_type).itemsize + n * np.dtype(p.type).itemsize
    fields, k = [], iter(lengths)
    for i, p in enumerate(element.properties):
        if p.count_type is None:
            fields.append((f"v{i}", order + p.type))
        else:
            fields += [(f"n{i}", order + p.count_type), (f"v{i}", order + p.type, (next(k),))]
    dtype = np.dtype(fields)
    if at + element.count * dtype.itemsize <= len(data):
        rows = np.frombuffer(data, dtype, element.count, at)
        if all((rows[f"n{i}"] == rows[f"n{i}"][:1]).all() for i, p in enumerate(element.properties)
               if p.count_type is not None):
            values = {p.name: rows[f"v{i}"] if p.count_type is None else
                      (rows[f"v{i}"].reshape(-1), rows[f"n{i}"].astype(np.int64))
                      for i, p in enumerate(element.properties)}
            return values, at + element.count * dtype.itemsize
    return _rows_by_offsets(element, at, len(data), _BinaryCounts(data, order),
                            lambda p, where: _gathered(data, order + p.type, where), binary=True)


def _rows_by_offsets(element: Element, at: int, end: int, count_at, gather, binary: bool):
    """(values, position after the element) of rows whose lists differ in
    length: a loop walks the rows reading only the list counts, then every
    property's values are gathered at once (one numpy call per property
    instead of one per row). Positions are bytes of a binary body (binary)
    or numbers of an ASCII one, up to end; count_at(p, i) gives the count of
    list p at position i and the positions it takes, gather(p, where) the
    values of p at the positions where (an int64 array)."""
    step = {p.name: np.dtype(p.type).itemsize if binary else 1 for p in element.properties}
    starts = {p.name: [] for p in element.properties}
    counts = {p.name: [] for p in element.properties if p.count_type is not None}
    pos = at
    try:
        for _ in range(element.count):
            for p in element.properties:
                n = 1
                if p.count_type is not None:
                    value, taken = count_at(p, pos)
                    n = _list_length(element, value)
                    counts[p.name].append(n)
                    pos += taken
                starts[p.name].append(pos)
                pos += step[p.name] * n
    except (IndexError, struct.error) as exc:
        raise ValueError("past the end") from exc
    if pos > end:
        raise ValueError("past the end")
    values = {}
    for p in element.properties:
        first = np.array(starts[p.name], dtype=np.int64)
        if p.count_type is None:
            values[p.name] = gather(p, first)
            continue
        n = np.array(counts[p.name], dtype=np.int64)
        where = np.repeat(first, n) + (np.arange(n.sum()) - np.repeat(_starts(n), n)) * step[p.name]
        values[p.name] = (gather(p, where), n)
    return values, pos


class _BinaryCounts:
    """count_at of _rows_by_offsets for a binary body: (count, bytes it takes)."""

    def __init__(self, data: bytes, order: str):
        self.data, self.order, self.readers = data, order, {}

    def __call__(self, p: Property, at: int):
        reader = self.readers.get(p.count_type)
        if reader is None:
            reader = self.readers[p.count_type] = struct.Struct(self.order + np.dtype(p.count_type).char)
        return reader.unpack_from(self.data, at)[0], reader.size


def _gathered(data: bytes, kind: str, first: np.ndarray) -> np.ndarray:
    """The values of numpy type kind whose bytes start at the offsets first."""
    if not len(first):
        return np.zeros(0, kind)
    raw = np.frombuffer(data, np.uint8)
    return raw[first[:, None] + np.arange(np.dtype(kind).itemsize)].reshape(-1).view(kind)


def _ascii_rows(element: Element, numbers: np.ndarray, at: int):
    """(values, index after the element) from the body's numbers. Rows as long
    as the first one are read as one block; other lengths, row by row."""
    if element.count * len(element.properties) > len(numbers) - at:  # every row holds a value per property
        raise ValueError("past the end")
    width, lengths, probe = 0, [], at
    for p in element.properties:
        n = _list_length(element, numbers[probe] if p.count_type is not None and element.count else 0)
        lengths.append(n)
        step = 1 if p.count_type is None else 1 + n
        width, probe = width + step, probe + step
    end = at + element.count * width
    if end <= len(numbers):
        rows = numbers[at:end].reshape(element.count, width)
        values, col = {}, 0
        for p, n in zip(element.properties, lengths):
            if p.count_type is None:
                values[p.name], col = rows[:, col], col + 1
            elif (rows[:, col] == n).all():
                values[p.name], col = (rows[:, col + 1:col + 1 + n].reshape(-1), rows[:, col].astype(np.int64)), col + 1 + n
            else:
                break
        else:
            return values, end
    return _rows_by_offsets(element, at, len(numbers), lambda p, i: (numbers[i], 1),
                            lambda p, where: numbers[where], binary=False)


def read_elements(data: bytes, fmt: str, elements: list, body: int) -> dict:
    """name -> values of every element. ValueError where the body holds
    fewer or more values than the header declares (counts that lie would
    shift every element after them), or a non-integer where an integer is."""
    out = {}
    if fmt == "ascii":
        source, at, rows = _ascii_numbers(data[body:]), 0, _ascii_rows
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        source, at = data, body
        def rows(element, data, at):
            return _binary_rows(element, data, at, order)
    for element in elements:
        try:
            out[element.name], at = rows(element, source, at)
        except _ImpossibleList:
            raise
        except ValueError as exc:  # "past the end", or numpy's "buffer is smaller than requested size"
            raise ValueError(f"the file ends inside its '{element.name}' element") from exc
        if fmt == "ascii":
            _require_integers(element, out[element.name])
    left = len(source) - at if fmt == "ascii" else len(data[at:].rstrip(b"\r\n "))
    if left:
        raise ValueError(f"its body holds {left} {'values' if fmt == 'ascii' else 'bytes'} more than "
                         "its header declares")
    return out


def _require_integers(element: Element, values: dict) -> None:
    """ValueError where an ASCII body gives a non-integer to an integer property."""
    for p in element.properties:
        v = values[p.name] if p.count_type is None else values[p.name][0]
        if np.dtype(p.type).kind in "iu" and len(v) and not (v == np.floor(v)).all():
            raise ValueError(f"property '{p.name}' of its '{element.name}' element is an integer, "
                             "but the body gives a fraction")


def _ascii_numbers(body: bytes) -> np.ndarray:
    """Every number of an ASCII body, in order (without a Python object per number)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", DeprecationWarning)  # numpy 1.x: a word that is no number
        try:
            return np.fromstring(body, dtype=np.float64, sep=" ")
        except (DeprecationWarning, ValueError) as exc:
            raise ValueError("a value of its ASCII body is not a number") from exc


def fan(counts: np.ndarray):
    """Corners (T, 3) of the fan triangles of polygons of `counts` corners,
    indices into their corners laid end to end, and the polygon of each
    triangle; polygons of fewer than 3 corners give none."""
    counts = np.asarray(counts, dtype=np.int64)
    if (counts == 3).all():  # a triangle mesh, as scans are: nothing to fan
        return np.arange(3 * len(counts)).reshape(-1, 3), np.arange(len(counts))
    starts = _starts(counts)
    per_polygon = np.maximum(counts - 2, 0)
    polygon = np.repeat(np.arange(len(counts)), per_polygon)
    first_triangle = _starts(per_polygon)
    i = np.arange(len(polygon)) - first_triangle[polygon] + 1
    base = starts[polygon]
    return np.stack([base, base + i, base + i + 1], axis=1), polygon


def _vertex_uvs(vertex: dict):
    for u, v in _VERTEX_UV_NAMES:
        if u in vertex and v in vertex:
            return np.stack([vertex[u], vertex[v]], axis=1).astype(np.float64)
    return None


def _vertex_colours(vertex: dict, types: dict):
    """red, green, blue (and alpha) as MeshLab and scanner apps write them:
    integers at their declared type's full scale (ASCII values arrive as
    floats), floats in 0..1. types: property name -> numpy type code."""
    if not all(c in vertex for c in ("red", "green", "blue")):
        return None
    out = np.ones((len(vertex["red"]), 4), np.float32)
    for k, c in enumerate(("red", "green", "blue", "alpha")):
        if c in vertex:
            kind = np.dtype(types[c])
            scale = np.iinfo(kind).max if kind.kind in "iu" else 1.0
            out[:, k] = np.clip(vertex[c] / scale, 0.0, 1.0)
    return out


def read(data: bytes) -> PlyMesh:
    """The mesh of a PLY file's bytes; ValueError saying what is wrong otherwise."""
    fmt, elements, textures, body = parse_header(data)
    values = read_elements(data, fmt, elements, body)
    vertex, face = values.get("vertex", {}), values.get("face", {})
    for name, value in vertex.items():
        if isinstance(value, tuple) and name in _SCALARS:
            raise ValueError(f"property '{name}' must be a single value, not a list")
    if not all(c in vertex for c in "xyz"):
        raise ValueError("no vertex positions (x, y, z)")
    positions = np.stack([vertex[c] for c in "xyz"], axis=1).astype(np.float64)
    indices = face.get("vertex_indices", face.get("vertex_index"))
    if not isinstance(indices, tuple):
        raise ValueError("no faces (a 'vertex_indices' list)")
    corners, polygon = fan(indices[1])
    triangles = indices[0].astype(np.int64)[corners] if len(corners) else np.zeros((0, 3), np.int64)
    if len(triangles) and (triangles.min() < 0 or triangles.max() >= len(positions)):
        raise ValueError(f"a face refers to a vertex outside 0..{len(positions) - 1}")
    texnumber = face.get("texnumber")
    texnumber = np.zeros(len(indices[1]), np.int64) if texnumber is None or isinstance(texnumber, tuple) \
        else texnumber.astype(np.int64)
    notes = _texnumber_notes(texnumber[np.asarray(indices[1]) >= 3], len(textures))
    texnumber = texnumber[polygon]
    uvs = None
    texcoord = face.get("texcoord")
    if isinstance(texcoord, tuple):
        uvs, whole = _face_uvs(texcoord, indices[1], corners, polygon)
        texnumber[~whole] = -1  # a face without two values per corner has no texture
        if not whole.all():
            notes.append(f"texcoord lists without two values per corner leave {np.unique(polygon[~whole]).size} "
                         "face(s) untextured")
    elif (per_vertex := _vertex_uvs(vertex)) is not None:
        uvs = per_vertex[triangles]
    # Blender's mesh validation would turn them into zeros without a word.
    # A vertex no face uses (a point cloud's, say) goes unread.
    if not np.isfinite(positions[triangles]).all():
        raise ValueError("a vertex position is not a finite number (NaN or infinity)")
    if uvs is not None and not np.isfinite(uvs).all():
        raise ValueError("a texture coordinate is not a finite number (NaN or infinity)")
    types = {p.name: p.type for e in elements if e.name == "vertex" for p in e.properties}
    normal = [vertex.get(c) for c in ("nx", "ny", "nz")]  # lists there are no normals: left out
    normals = np.stack(normal, axis=1).astype(np.float64) \
        if all(isinstance(c, np.ndarray) for c in normal) else None
    return PlyMesh(positions, triangles, uvs, texnumber, textures, _vertex_colours(vertex, types), notes, normals)


def _texnumber_notes(texnumber: np.ndarray, texture_count: int) -> list:
    """A note when faces name a texture the header has no TextureFile for
    (texnumber per face; a negative one is how OpenMVS says a face has none,
    and a header without any leaves every face untextured, which the caller says)."""
    outside = int((texnumber >= texture_count).sum()) if texture_count else 0
    if not outside:
        return []
    return [f"texture numbers outside the header's {texture_count} TextureFile line(s) (0..{texture_count - 1}) "
            f"leave {outside} face(s) untextured"]


def _face_uvs(texcoord, corner_counts: np.ndarray, corners: np.ndarray, polygon: np.ndarray):
    """(UVs (T, 3, 2) of the fan triangles from per-face texcoord lists,
    (T,) whether their face held two values per corner; the others get 0)."""
    values, counts = texcoord
    whole = counts == 2 * corner_counts
    if whole.all() and (corner_counts == 3).all():  # triangles only (fan kept them in order), 6 values each
        return np.asarray(values, dtype=np.float64).reshape(-1, 3, 2), whole
    starts = _starts(counts)
    local = corners - _starts(corner_counts)[polygon][:, None]  # corner of each triangle within its face
    at = np.where(whole[polygon][:, None], starts[polygon][:, None] + 2 * local, 0)
    values = np.asarray(values, dtype=np.float64)
    if not len(values):
        return np.zeros((len(corners), 3, 2)), whole[polygon]
    uvs = np.stack([values[at], values[np.minimum(at + 1, len(values) - 1)]], axis=-1)
    uvs[~whole[polygon]] = 0.0
    return uvs, whole[polygon]


def face_textures(mesh: PlyMesh, folder: str):
    """(paths of the header's textures whose files exist in folder, in order;
    per face (F,) the index into them, -1 where its texture is missing, out
    of range or none; the names of the textures missing)."""
    index = np.full(len(mesh.textures) + 1, -1, dtype=np.int64)  # the last: no such texture
    found, missing = [], []
    for k, name in enumerate(mesh.textures):
        path = _texture_file(folder, name)
        if path:
            index[k] = len(found)
            found.append(path)
        else:
            missing.append(readable(name))
    known = (mesh.texnumber >= 0) & (mesh.texnumber < len(mesh.textures))
    return found, index[np.where(known, mesh.texnumber, len(mesh.textures))], missing


def _texture_file(folder: str, name: str) -> str:
    """The file a TextureFile name gives in folder ('' if none): as written,
    then as shown (a Latin-1 name on a system whose file names are Unicode),
    each also by its file name alone (a path from another machine, C:\\...)."""
    for written in dict.fromkeys((name, readable(name))):
        path = os.path.join(folder, written.replace("\\", "/"))
        for candidate in (path, os.path.join(folder, os.path.basename(path))):
            if os.path.isfile(candidate):
                return candidate
    return ""
