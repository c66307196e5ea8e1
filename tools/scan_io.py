"""Reads textured scans (OBJ+MTL, glTF, GLB, PLY) into plain numpy arrays, without Blender.

Used by the tests, the benchmark and the command-line demo; the add-on reads
meshes through bpy instead. Polygons are fan-triangulated (OBJ by the native
reader, _native.read_obj; PLY by the add-on's ply_io), because the native stages take
triangles only.
"""
from __future__ import annotations

import base64
import io
import json
import struct
import urllib.parse
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
    """(H, W, C) uint8 with row 0 at the bottom (v = 0), as Blender stores
    pixels; C is 1 (grey), 3 or 4. 8-bit RGB and RGBA PNGs are decoded as the
    add-on decodes them (png_files.decode_png: zlib, then the row filters
    undone natively straight into Blender's row order, skipping Pillow's copy
    into numpy and the flip); other files, and PNGs it refuses, by Pillow."""
    from PIL import Image
    from atlas_defrag import png_files

    data = bytes(source) if isinstance(source, (bytes, bytearray)) else Path(source).read_bytes()
    pixels = png_files.decode_png_or_none(data)
    if pixels is not None:
        return pixels
    Image.MAX_IMAGE_PIXELS = None  # scans routinely exceed Pillow's bomb guard
    img = Image.open(io.BytesIO(data))
    if img.mode.startswith("I;16") or img.mode == "I":  # 16-bit grey: Pillow's convert would clip it
        pixels = (np.asarray(img).astype(np.uint32) >> 8).clip(0, 255).astype(np.uint8)[::-1]
        return np.ascontiguousarray(pixels[..., None])
    if img.mode not in ("L", "RGB", "RGBA"):
        img = img.convert("RGBA" if "A" in img.getbands() else "RGB")
    pixels = np.asarray(img)[::-1]
    return np.ascontiguousarray(pixels[..., None] if pixels.ndim == 2 else pixels)


def image_size(source) -> tuple[int, int]:
    from PIL import Image

    Image.MAX_IMAGE_PIXELS = None
    with Image.open(io.BytesIO(source) if isinstance(source, (bytes, bytearray)) else source) as img:
        return img.size


def load(path) -> Scan:
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".obj":
        return load_obj(path)
    if suffix == ".glb":
        return load_glb(path)
    if suffix == ".gltf":
        return load_gltf(path)
    if suffix == ".ply":
        return load_ply(path)
    raise ValueError(f"unsupported scan format: {path.suffix} (OBJ, glTF, GLB or PLY)")


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
    """The geometry through the native reader (_native.read_obj): parsing in
    Python was the command-line entry's slowest stage on large scans
    (bench/README.md)."""
    from atlas_defrag import _native

    obj = _native.read_obj(str(path))
    tris, uv_idx = obj["triangles"], obj["texcoord_index"]
    has_uv = uv_idx[:, 0] >= 0
    vt = obj["texcoords"]
    uvs = vt[np.maximum(uv_idx, 0)] if len(vt) else np.zeros((len(tris), 3, 2))
    uvs[~has_uv] = 0.0

    textures = _read_mtl_textures(path, obj["material_libraries"])
    pages, page_of = [], {}
    material_page = np.full(len(obj["materials"]) + 1, -1, dtype=np.int32)  # the last: no usemtl
    used, first_face = np.unique(obj["face_material"][has_uv], return_index=True)
    for m in used[np.argsort(first_face)]:  # pages in the order faces first use them
        tex = textures.get(obj["materials"][m]) if m >= 0 else None
        if tex is None or not tex.exists():
            continue
        if tex not in page_of:
            page_of[tex] = len(pages)
            pages.append(tex)
        material_page[m] = page_of[tex]
    face_page = np.where(has_uv, material_page[obj["face_material"]], -1).astype(np.int32)
    sizes = np.array([image_size(p) for p in pages], dtype=np.int32).reshape(-1, 2)
    return Scan(obj["positions"], tris, uvs, face_page, sizes, pages, [{"base_color": p} for p in pages])


# ---- PLY ------------------------------------------------------------------

def load_ply(path: Path) -> Scan:
    """Texture k is the header's k-th TextureFile (faces with texnumber k);
    faces whose texture is missing, or without UVs, are left untextured."""
    from atlas_defrag import ply_io

    mesh = ply_io.read(path.read_bytes())
    found, face_page, _ = ply_io.face_textures(mesh, str(path.parent))
    pages = [Path(p) for p in found]
    face_page = face_page.astype(np.int32) if mesh.uvs is not None else np.full(len(mesh.triangles), -1, np.int32)
    uvs = mesh.uvs if mesh.uvs is not None else np.zeros((len(mesh.triangles), 3, 2))
    sizes = np.array([image_size(p) for p in pages], dtype=np.int32).reshape(-1, 2)
    return Scan(mesh.positions, mesh.triangles.astype(np.int32), uvs, face_page, sizes, pages,
                [{"base_color": p} for p in pages])


# ---- glTF and GLB -----------------------------------------------------------

_COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _accessor(gltf: dict, buffers: list, index: int) -> np.ndarray:
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    binary = buffers[view["buffer"]]
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


def _uri_bytes(uri: str, folder: Path) -> bytes:
    """A glTF uri: an embedded data: URI, or a file beside the .gltf."""
    if uri.startswith("data:"):
        return base64.b64decode(uri.split(",", 1)[1])
    return (folder / urllib.parse.unquote(uri)).read_bytes()


class UnreadableTexture(ValueError):
    """A texture whose images are all in formats this reader cannot decode."""


def _texture_source(texture: dict) -> int:
    """The image of a texture: its own source (the PNG or JPEG fallback when
    there is one), else the WebP one of EXT_texture_webp, which Pillow reads.
    UnreadableTexture for images only in formats Pillow cannot read (KTX2)."""
    if "source" in texture:
        return texture["source"]
    extensions = texture.get("extensions", {})
    if "source" in extensions.get("EXT_texture_webp", {}):
        return extensions["EXT_texture_webp"]["source"]
    raise UnreadableTexture(f"a texture has no image this reader can decode ({', '.join(extensions) or 'no source'})")


def _image_bytes(gltf: dict, buffers: list, folder: Path, texture_index: int) -> bytes:
    image = gltf["images"][_texture_source(gltf["textures"][texture_index])]
    if "uri" in image:
        return _uri_bytes(image["uri"], folder)
    view = gltf["bufferViews"][image["bufferView"]]
    start = view.get("byteOffset", 0)
    return buffers[view["buffer"]][start:start + view["byteLength"]]


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
    roots = gltf["scenes"][gltf.get("scene", 0)].get("nodes", []) if gltf.get("scenes") else range(len(nodes))
    # Each entry carries its ancestors: a node listed among its own
    # descendants would otherwise be walked forever.
    stack = [(n, np.eye(4), frozenset()) for n in roots]
    while stack:
        n, parent, ancestors = stack.pop()
        if n in ancestors:
            raise ValueError(f"glTF node {n} is its own ancestor (the node hierarchy has a cycle)")
        world = parent @ local(nodes[n])
        if "mesh" in nodes[n]:
            yield nodes[n]["mesh"], world
        stack.extend((c, world, ancestors | {n}) for c in nodes[n].get("children", []))


def load_glb(path: Path) -> Scan:
    data = path.read_bytes()
    if len(data) < 20 or struct.unpack_from("<I", data, 0)[0] != 0x46546C67:
        raise ValueError("not a binary glTF file")
    json_len, _ = struct.unpack_from("<II", data, 12)
    gltf = json.loads(data[20:20 + json_len])
    bin_offset = 20 + json_len
    chunk = b""
    if bin_offset + 8 <= len(data):
        bin_len, _ = struct.unpack_from("<II", data, bin_offset)
        chunk = data[bin_offset + 8:bin_offset + 8 + bin_len]
    # Buffer 0 without a uri is the binary chunk; any other is a uri.
    return _checked_gltf(path, gltf, lambda: [chunk if "uri" not in b else _uri_bytes(b["uri"], path.parent)
                                              for b in gltf.get("buffers", [])])


def load_gltf(path: Path) -> Scan:
    """A .gltf file: JSON, with buffers and images in files beside it or in data: URIs."""
    gltf = json.loads(path.read_text(encoding="utf-8"))
    return _checked_gltf(path, gltf, lambda: [_uri_bytes(b["uri"], path.parent) for b in gltf.get("buffers", [])])


# Extensions that change what the accessors or UVs mean: read without them, a
# scan would come out wrong rather than fail.
_UNREAD_EXTENSIONS = {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_texture_transform"}


def _checked_gltf(path: Path, gltf, read_buffers) -> Scan:
    """The scan of a parsed glTF, or ValueError saying what is wrong with it:
    a glTF 1.0 file, a missing buffer or a malformed field would otherwise
    surface as a bare KeyError or TypeError, and a cycle of nodes as a hang."""
    version = str(gltf.get("asset", {}).get("version", "")) if isinstance(gltf, dict) else ""
    if not version.startswith("2"):
        raise ValueError(f"not a glTF 2.0 file (asset version {version or 'missing'})")
    used = set(gltf.get("extensionsRequired", [])) | set(gltf.get("extensionsUsed", []))
    if used & _UNREAD_EXTENSIONS:
        raise ValueError(f"uses {', '.join(sorted(used & _UNREAD_EXTENSIONS))}, which this reader does not "
                         "support")
    try:
        scan = _scan_from_gltf(gltf, read_buffers(), path.parent)
    except UnreadableTexture:
        raise
    except OSError as exc:
        raise ValueError(f"a file it refers to cannot be read: {exc}") from exc
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, struct.error) as exc:
        raise ValueError(f"malformed glTF ({type(exc).__name__}: {exc})") from exc
    if scan is None:
        raise ValueError("no triangle mesh in the file")
    return scan


def _primitive_triangles(gltf: dict, buffers: list, prim: dict, vertex_count: int) -> np.ndarray:
    """(T, 3) vertex indices; a primitive without indices lists its vertices in order."""
    if "indices" not in prim:
        return np.arange(vertex_count - vertex_count % 3, dtype=np.int64).reshape(-1, 3)
    return _accessor(gltf, buffers, prim["indices"]).reshape(-1, 3).astype(np.int64)


def _colour_texture(material: dict):
    """The base colour texture slot of a glTF material, or None. Older exports
    (Sketchfab among them) give it as the diffuse texture of the
    specular-glossiness extension only."""
    return material.get("pbrMetallicRoughness", {}).get("baseColorTexture") or material.get(
        "extensions", {}).get("KHR_materials_pbrSpecularGlossiness", {}).get("diffuseTexture")


def _material_maps(gltf: dict, buffers: list, folder: Path, material: dict) -> dict:
    """role -> image bytes of a textured material: base colour, then the
    normal, occlusion, metallic-roughness and emission maps it has. A map
    only in a format Pillow cannot read is left out: the colour still bakes."""
    pbr = material.get("pbrMetallicRoughness", {})
    roles = {"base_color": _image_bytes(gltf, buffers, folder, _colour_texture(material)["index"])}
    for role, slot in (("normal", material.get("normalTexture")), ("occlusion", material.get("occlusionTexture")),
                       ("metallic_roughness", pbr.get("metallicRoughnessTexture")),
                       ("emission", material.get("emissiveTexture"))):
        if slot is not None:
            try:
                roles[role] = _image_bytes(gltf, buffers, folder, slot["index"])
            except UnreadableTexture:
                pass
    return roles


def _scan_from_gltf(gltf: dict, buffers: list, folder: Path):
    """The scan, or None when no node holds a triangle primitive."""
    positions, tris, uvs, face_page = [], [], [], []
    page_of, maps = {}, []
    base = 0
    for mesh_index, world in _node_matrices(gltf):
        for prim in gltf["meshes"][mesh_index]["primitives"]:
            if prim.get("mode", 4) != 4:
                continue
            pos = _accessor(gltf, buffers, prim["attributes"]["POSITION"]).astype(np.float64)
            pos = pos @ world[:3, :3].T + world[:3, 3]
            idx = _primitive_triangles(gltf, buffers, prim, len(pos))
            material = gltf["materials"][prim["material"]] if "material" in prim else {}
            page = -1
            if "TEXCOORD_0" in prim["attributes"]:
                uv = _accessor(gltf, buffers, prim["attributes"]["TEXCOORD_0"]).astype(np.float64)
                uv[:, 1] = 1.0 - uv[:, 1]  # glTF puts v = 0 at the top
                uvs.append(uv[idx])
                if _colour_texture(material) is not None:
                    if prim.get("material") not in page_of:
                        page_of[prim.get("material")] = len(maps)
                        maps.append(_material_maps(gltf, buffers, folder, material))
                    page = page_of[prim.get("material")]
            else:
                uvs.append(np.zeros((len(idx), 3, 2)))
            positions.append(pos)
            tris.append(idx + base)
            face_page.append(np.full(len(idx), page, dtype=np.int32))
            base += len(pos)
    if not tris:
        return None
    pages = [m["base_color"] for m in maps]
    sizes = np.array([image_size(p) for p in pages], dtype=np.int32).reshape(-1, 2)
    return Scan(np.concatenate(positions), np.concatenate(tris).astype(np.int32), np.concatenate(uvs),
                np.concatenate(face_page), sizes, pages, maps)
