"""Reads textured scans (OBJ+MTL, GLB) into plain numpy arrays, without Blender.

Used by the tests, the benchmark and the command-line demo; the add-on reads
meshes through bpy instead. Polygons are fan-triangulated here, because the
native module takes triangles only.
"""
from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Scan:
    positions: np.ndarray          # (V, 3) float64
    triangles: np.ndarray          # (F, 3) int32
    uvs: np.ndarray                # (F, 3, 2) float64, page units, v up
    face_page: np.ndarray          # (F,) int32, -1 for faces without texture
    page_sizes: np.ndarray         # (P, 2) int32, width and height
    page_images: list = field(default_factory=list)  # per page: Path or bytes of the base colour image
    maps: list = field(default_factory=list)         # per page: {role: Path or bytes}


def load_image(source) -> np.ndarray:
    """(H, W, C) uint8 with row 0 at the bottom (v = 0), as Blender stores pixels."""
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = None  # scans routinely exceed Pillow's bomb guard
    img = Image.open(io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source)
    if img.mode not in ("RGB", "RGBA"):
        img = img.convert("RGBA" if "A" in img.getbands() else "RGB")
    return np.ascontiguousarray(np.asarray(img)[::-1])


def image_size(source) -> tuple[int, int]:
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = None
    with Image.open(io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source) as img:
        return img.size


def load(path) -> Scan:
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return load_obj(path)
    if path.suffix.lower() == ".glb":
        return load_glb(path)
    raise ValueError(f"unsupported scan format: {path.suffix}")


# ---- OBJ ------------------------------------------------------------------

def _read_mtl_textures(obj_path: Path, mtllibs: list[str]) -> dict[str, Path]:
    textures: dict[str, Path] = {}
    for lib in mtllibs:
        mtl = obj_path.parent / lib
        if not mtl.exists():
            continue
        current = None
        for line in mtl.read_text(errors="replace").splitlines():
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "newmtl":
                current = " ".join(parts[1:])
            elif parts[0] == "map_Kd" and current is not None:
                textures[current] = obj_path.parent / parts[-1].replace("\\", "/")
    return textures


def load_obj(path: Path) -> Scan:
    verts, texcoords, faces, face_mtl, mtllibs = [], [], [], [], []
    material = None
    with open(path, errors="replace") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append(line.split()[1:4])
            elif line.startswith("vt "):
                texcoords.append(line.split()[1:3])
            elif line.startswith("f "):
                corners = [c.split("/") for c in line.split()[1:]]
                for i in range(1, len(corners) - 1):  # fan triangulation
                    faces.append((corners[0], corners[i], corners[i + 1]))
                    face_mtl.append(material)
            elif line.startswith("usemtl"):
                material = line.split(maxsplit=1)[1].strip() if len(line.split()) > 1 else None
            elif line.startswith("mtllib"):
                mtllibs.append(line.split(maxsplit=1)[1].strip())
    positions = np.asarray(verts, dtype=np.float64)
    vt = np.asarray(texcoords, dtype=np.float64).reshape(-1, 2)
    n_v, n_t = len(positions), len(vt)

    def index(token: str, count: int) -> int:
        i = int(token)
        return i - 1 if i > 0 else count + i

    tris = np.array([[index(c[0], n_v) for c in f] for f in faces], dtype=np.int32)
    has_uv = np.array([all(len(c) > 1 and c[1] for c in f) for f in faces])
    uv_idx = np.array([[index(c[1], n_t) if h else 0 for c in f] for f, h in zip(faces, has_uv)], dtype=np.int64)
    uvs = vt[uv_idx] if n_t else np.zeros((len(faces), 3, 2))

    textures = _read_mtl_textures(path, mtllibs)
    pages, page_of = [], {}
    face_page = np.full(len(faces), -1, dtype=np.int32)
    for f, (m, h) in enumerate(zip(face_mtl, has_uv)):
        tex = textures.get(m)
        if not h or tex is None or not tex.exists():
            continue
        if tex not in page_of:
            page_of[tex] = len(pages)
            pages.append(tex)
        face_page[f] = page_of[tex]
    sizes = np.array([image_size(p) for p in pages], dtype=np.int32).reshape(-1, 2)
    return Scan(positions, tris, uvs, face_page, sizes, pages, [{"base_color": p} for p in pages])


# ---- GLB ------------------------------------------------------------------

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _accessor(gltf: dict, binary: bytes, index: int) -> np.ndarray:
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    dtype = np.dtype(_COMPONENTS[acc["componentType"]])
    width = _WIDTH[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    stride = view.get("byteStride", dtype.itemsize * width)
    raw = np.frombuffer(binary, dtype=np.uint8, count=stride * (acc["count"] - 1) + dtype.itemsize * width,
                        offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, (acc["count"], dtype.itemsize * width), (stride, 1))
    values = np.ascontiguousarray(rows).view(dtype).reshape(acc["count"], width)
    if acc.get("normalized"):
        values = values.astype(np.float64) / np.iinfo(dtype).max
    return values


def _image_bytes(gltf: dict, binary: bytes, texture_index: int) -> bytes:
    image = gltf["images"][gltf["textures"][texture_index]["source"]]
    view = gltf["bufferViews"][image["bufferView"]]
    start = view.get("byteOffset", 0)
    return binary[start:start + view["byteLength"]]


def _node_matrices(gltf: dict):
    """World matrix of every node that holds a mesh."""
    def local(node):
        if "matrix" in node:
            return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
        t = np.eye(4)
        x, y, z, w = node.get("rotation", [0, 0, 0, 1])
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        t[:3, :3] = r * np.asarray(node.get("scale", [1, 1, 1]))
        t[:3, 3] = node.get("translation", [0, 0, 0])
        return t

    nodes = gltf.get("nodes", [])
    roots = gltf["scenes"][gltf.get("scene", 0)]["nodes"] if gltf.get("scenes") else range(len(nodes))
    stack = [(n, np.eye(4)) for n in roots]
    while stack:
        n, parent = stack.pop()
        world = parent @ local(nodes[n])
        if "mesh" in nodes[n]:
            yield nodes[n]["mesh"], world
        stack.extend((c, world) for c in nodes[n].get("children", []))


def load_glb(path: Path) -> Scan:
    data = path.read_bytes()
    magic, _version, _length = struct.unpack_from("<III", data, 0)
    if magic != 0x46546C67:
        raise ValueError(f"{path} is not a binary glTF file")
    json_len, _ = struct.unpack_from("<II", data, 12)
    gltf = json.loads(data[20:20 + json_len])
    bin_offset = 20 + json_len
    bin_len, _ = struct.unpack_from("<II", data, bin_offset)
    binary = data[bin_offset + 8:bin_offset + 8 + bin_len]

    positions, tris, uvs, face_page = [], [], [], []
    pages, page_of, maps = [], {}, []
    base = 0
    for mesh_index, world in _node_matrices(gltf):
        for prim in gltf["meshes"][mesh_index]["primitives"]:
            if prim.get("mode", 4) != 4:
                continue
            pos = _accessor(gltf, binary, prim["attributes"]["POSITION"]).astype(np.float64)
            pos = pos @ world[:3, :3].T + world[:3, 3]
            idx = _accessor(gltf, binary, prim["indices"]).reshape(-1, 3).astype(np.int64)
            material = gltf["materials"][prim["material"]] if "material" in prim else {}
            pbr = material.get("pbrMetallicRoughness", {})
            tex = pbr.get("baseColorTexture")
            if "TEXCOORD_0" in prim["attributes"]:
                uv = _accessor(gltf, binary, prim["attributes"]["TEXCOORD_0"]).astype(np.float64)
                uv[:, 1] = 1.0 - uv[:, 1]  # glTF puts v = 0 at the top
                uvs.append(uv[idx])
            else:
                uvs.append(np.zeros((len(idx), 3, 2)))
                tex = None
            page = -1
            if tex is not None:
                key = prim.get("material")
                if key not in page_of:
                    page_of[key] = len(pages)
                    pages.append(_image_bytes(gltf, binary, tex["index"]))
                    roles = {"base_color": pages[-1]}
                    for role, slot in (("normal", material.get("normalTexture")),
                                       ("occlusion", material.get("occlusionTexture")),
                                       ("metallic_roughness", pbr.get("metallicRoughnessTexture")),
                                       ("emission", material.get("emissiveTexture"))):
                        if slot is not None:
                            roles[role] = _image_bytes(gltf, binary, slot["index"])
                    maps.append(roles)
                page = page_of[key]
            positions.append(pos)
            tris.append(idx + base)
            face_page.append(np.full(len(idx), page, dtype=np.int32))
            base += len(pos)
    sizes = np.array([image_size(p) for p in pages], dtype=np.int32).reshape(-1, 2)
    return Scan(np.concatenate(positions), np.concatenate(tris).astype(np.int32), np.concatenate(uvs),
                np.concatenate(face_page), sizes, pages, maps)
